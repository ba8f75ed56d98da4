"""Typed settings of a RealSense camera: model, streams, visual preset, exposure, post-processing, fault handling."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from drivers.camera.realsense_models import RealSenseModel, Stream, model_named
from drivers.errors import CameraError

ANY_STREAM = Stream((640, 480), (640, 480), 30)  # a RealSense the model table does not hold: every model offers it
HOLE_FILLING = {"fill_from_left": 0, "farest_from_around": 1, "nearest_from_around": 2}


@dataclass(frozen=True)
class FilterConfig:
    """librealsense depth post-processing, run in this order before alignment: decimation ->
    depth-to-disparity -> spatial -> temporal -> disparity-to-depth -> hole filling.

    Defaults suit a moving object: edge-preserving spatial smoothing only. The temporal filter
    averages over frames and smears motion (off); hole filling invents depth at edges (off);
    decimation (1 = off) lowers depth resolution, which alignment then spreads back over colour.
    """

    decimation: int = 1
    spatial: bool = True
    spatial_alpha: float = 0.5
    spatial_delta: float = 20.0
    temporal: bool = False
    temporal_alpha: float = 0.4
    temporal_delta: float = 20.0
    hole_filling: str | None = None  # one of HOLE_FILLING, None = off

    def __post_init__(self) -> None:
        if self.decimation not in (1, 2, 3, 4, 5, 6, 7, 8):
            raise CameraError(f"depth filter: decimation must be 1 (off) to 8, got {self.decimation}")
        for name in ("spatial_alpha", "temporal_alpha"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise CameraError(f"depth filter: {name} must be in (0, 1], got {getattr(self, name)}")
        if self.hole_filling is not None and self.hole_filling not in HOLE_FILLING:
            raise CameraError(
                f"depth filter: unknown hole_filling {self.hole_filling!r}; choose one of "
                f"{', '.join(HOLE_FILLING)} or leave it unset (off)"
            )

    @classmethod
    def none(cls) -> FilterConfig:
        """Raw depth: every filter off."""
        return cls(spatial=False)


@dataclass(frozen=True)
class RealSenseConfig:
    """A RealSense stream: colour RGB8 + depth Z16, depth aligned to colour.

    model: a name of the model table (`d415`, `d435`, ...) whose defaults and modes apply, or None for any
    RealSense (the connected camera's model then sets the defaults, when the table holds it). serial: None opens
    the only connected camera (of `model`). width, height: the colour stream's resolution, which frames have;
    depth_width, depth_height: the depth stream's (default: the colour's where the depth stream offers it, else the
    model's); fps: both streams' rate; None: the model's default (of a size, the side not given). visual_preset:
    one of the model's presets (None keeps the device's). depth_exposure_us / color_exposure: manual exposure in
    the sensor's units (depth: us; colour: 100 us steps on a D400), None = auto exposure. warmup_frames: frames
    dropped after start while auto exposure settles. frame_timeout_s, retries: a read waits frame_timeout_s per
    attempt and retries `retries` times before a hardware reset and reconnect; reset_wait_s: how long to wait for
    the camera to come back after the reset.
    """

    model: str | None = None
    serial: str | None = None
    width: int | None = None
    height: int | None = None
    depth_width: int | None = None
    depth_height: int | None = None
    fps: int | None = None
    visual_preset: str | None = None
    depth_exposure_us: float | None = None
    color_exposure: float | None = None
    warmup_frames: int = 30
    frame_timeout_s: float = 1.0
    retries: int = 2
    reset_wait_s: float = 10.0
    filters: FilterConfig = field(default_factory=FilterConfig)

    def __post_init__(self) -> None:
        if self.model is not None:
            model = model_named(self.model)
            self.stream(model)
            model.check_preset(self.visual_preset)
        for name in ("depth_exposure_us", "color_exposure"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise CameraError(f"{self.label}: {name} must be a positive number or unset (auto), got {value}")
        if self.warmup_frames < 0 or self.retries < 0:
            raise CameraError(f"{self.label}: warmup_frames and retries must be >= 0")
        if not (self.frame_timeout_s > 0 and self.reset_wait_s > 0):
            raise CameraError(f"{self.label}: frame_timeout_s and reset_wait_s must be positive")

    @property
    def label(self) -> str:
        """How messages name the camera: its model ("D435") or "RealSense"."""
        return self.model.upper() if self.model else "RealSense"

    def stream(self, model: RealSenseModel | None) -> Stream:
        """The resolutions and rate to stream from a camera of `model` (None: one the table does not hold, which
        gets what was asked, else 640x480 at 30 fps); CameraError when `model` does not offer them."""
        default = model.default if model is not None else ANY_STREAM
        color = _size(self.width, self.height, default.color)
        depth = _size(self.depth_width, self.depth_height, default.depth)
        if model is not None:
            return model.stream(color, depth, self.fps)
        color = color or ANY_STREAM.color
        return Stream(color, depth or color, self.fps or ANY_STREAM.fps)

    @classmethod
    def from_options(cls, serial: str | None = None, **options: object) -> RealSenseConfig:
        """A config from keyword options (RealSenseConfig fields; FilterConfig fields go to `filters`);
        an unknown option is a CameraError naming the valid ones."""
        own = {f.name for f in fields(cls)} - {"serial"}
        filter_names = {f.name for f in fields(FilterConfig)}
        unknown = set(options) - own - filter_names
        if unknown:
            raise CameraError(
                f"RealSense: unknown option(s) {', '.join(sorted(unknown))}; valid: "
                f"{', '.join(sorted(own | filter_names))}"
            )
        filters = options.pop("filters", None) or FilterConfig(
            **{k: options.pop(k) for k in list(options) if k in filter_names}
        )
        return cls(serial=serial, filters=filters, **options)  # type: ignore[arg-type]


def _size(width: int | None, height: int | None, default: tuple[int, int]) -> tuple[int, int] | None:
    """The size asked for, `default` filling the side not given; None when neither is."""
    if width is None and height is None:
        return None
    return (default[0] if width is None else width, default[1] if height is None else height)
