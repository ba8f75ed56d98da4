"""Typed settings of a RealSense D415: streams, visual preset, exposure, post-processing, fault handling."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from drivers.errors import CameraError

RESOLUTIONS = ((640, 480), (848, 480), (1280, 720))  # colour and depth both support these on a D415
FPS = (6, 15, 30, 60)  # 60 fps only up to 848x480
VISUAL_PRESETS = ("custom", "default", "hand", "high_accuracy", "high_density", "medium_density")
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
    """A D415 stream: colour RGB8 + depth Z16 at one resolution and rate, depth aligned to colour.

    serial: None opens the only connected camera. visual_preset: one of VISUAL_PRESETS (None keeps the
    device's). depth_exposure_us / color_exposure: manual exposure in the sensor's units (depth: us;
    colour: 100 us steps on a D415), None = auto exposure. warmup_frames: frames dropped after start
    while auto exposure settles. frame_timeout_s, retries: a read waits frame_timeout_s per attempt and
    retries `retries` times before a hardware reset and reconnect; reset_wait_s: how long to wait for
    the camera to come back after the reset.
    """

    serial: str | None = None
    width: int = 640
    height: int = 480
    fps: int = 30
    visual_preset: str | None = None
    depth_exposure_us: float | None = None
    color_exposure: float | None = None
    warmup_frames: int = 30
    frame_timeout_s: float = 1.0
    retries: int = 2
    reset_wait_s: float = 10.0
    filters: FilterConfig = field(default_factory=FilterConfig)

    def __post_init__(self) -> None:
        if (self.width, self.height) not in RESOLUTIONS:
            raise CameraError(
                f"D415: resolution {self.width}x{self.height} is not supported; choose one of "
                f"{', '.join(f'{w}x{h}' for w, h in RESOLUTIONS)}"
            )
        if self.fps not in FPS or (self.fps == 60 and self.width > 848):
            raise CameraError(
                f"D415: {self.fps} fps at {self.width}x{self.height} is not supported; choose one of "
                f"{', '.join(map(str, FPS))} fps (60 only up to 848x480)"
            )
        if self.visual_preset is not None and self.visual_preset not in VISUAL_PRESETS:
            raise CameraError(
                f"D415: unknown visual preset {self.visual_preset!r}; choose one of {', '.join(VISUAL_PRESETS)}"
            )
        for name in ("depth_exposure_us", "color_exposure"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise CameraError(f"D415: {name} must be a positive number or unset (auto), got {value}")
        if self.warmup_frames < 0 or self.retries < 0:
            raise CameraError("D415: warmup_frames and retries must be >= 0")
        if not (self.frame_timeout_s > 0 and self.reset_wait_s > 0):
            raise CameraError("D415: frame_timeout_s and reset_wait_s must be positive")

    @classmethod
    def from_options(cls, serial: str | None = None, **options: object) -> RealSenseConfig:
        """A config from keyword options (RealSenseConfig fields; FilterConfig fields go to `filters`);
        an unknown option is a CameraError naming the valid ones."""
        own = {f.name for f in fields(cls)} - {"serial"}
        filter_names = {f.name for f in fields(FilterConfig)}
        unknown = set(options) - own - filter_names
        if unknown:
            raise CameraError(
                f"D415: unknown option(s) {', '.join(sorted(unknown))}; valid: {', '.join(sorted(own | filter_names))}"
            )
        filters = options.pop("filters", None) or FilterConfig(
            **{k: options.pop(k) for k in list(options) if k in filter_names}
        )
        return cls(serial=serial, filters=filters, **options)  # type: ignore[arg-type]
