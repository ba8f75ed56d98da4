"""The RealSense model table (realsense_models.toml, data with its sources): what `--camera d435` and the other
model names set (resolutions, frame rates, presets), the depth unit, where colour comes from, the colour lens model
and the minimum range, and the check of a stream request against them."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.errors import CameraError
from drivers.toml_file import read_toml

TABLE = Path(__file__).with_name("realsense_models.toml")
Size = tuple[int, int]


def _size(text: str) -> Size:
    width, _, height = text.partition("x")
    return int(width), int(height)


def size_text(size: Size) -> str:
    return f"{size[0]}x{size[1]}"


@dataclass(frozen=True)
class Stream:
    """What one stream of a camera is asked for: colour (the output) and depth resolutions, and the frame rate."""

    color: Size
    depth: Size
    fps: int


@dataclass(frozen=True)
class RealSenseModel:
    """One entry of the table (see realsense_models.toml for each field's meaning)."""

    name: str
    product: str
    product_line: str
    source: str
    depth_unit_m: float
    color_sensor: str
    color_distortion: str
    presets: tuple[str, ...]
    default: Stream
    depth_modes: dict[Size, tuple[int, ...]]
    color_modes: dict[Size, tuple[int, ...]]
    min_range_table: tuple[tuple[int, float], ...]  # (depth image height, Min-Z m), heights increasing

    @property
    def color_from_depth_module(self) -> bool:
        """Whether colour comes from the depth module (a camera without a colour sensor of its own)."""
        return self.color_sensor == "Stereo Module"

    def min_range_m(self, depth_height: int) -> float:
        """The nearest depth the camera measures at a depth image `depth_height` pixels high (m)."""
        heights, ranges = zip(*self.min_range_table, strict=True)
        return float(np.interp(depth_height, heights, ranges))

    def stream(self, color: Size | None = None, depth: Size | None = None, fps: int | None = None) -> Stream:
        """The stream asked for, the model's defaults where None, checked against its modes: CameraError naming
        the model's choices. Depth follows a colour resolution asked for where the depth stream has it too."""
        color = color or self.default.color
        if depth is None:
            depth = color if color in self.depth_modes else self.default.depth
        fps = fps or self.default.fps
        for what, size, modes in (("colour", color, self.color_modes), ("depth", depth, self.depth_modes)):
            if size not in modes:
                raise CameraError(f"{self.name.upper()}: {what} resolution {size_text(size)} is not supported; "
                                  f"choose one of {', '.join(map(size_text, modes))}")
            if fps not in modes[size]:
                raise CameraError(f"{self.name.upper()}: {fps} fps is not offered for {what} at {size_text(size)}; "
                                  f"choose one of {', '.join(map(str, modes[size]))} fps")
        return Stream(color, depth, fps)

    def check_preset(self, preset: str | None) -> None:
        if preset is not None and preset not in self.presets:
            raise CameraError(f"{self.name.upper()}: unknown visual preset {preset!r}; choose one of "
                              f"{', '.join(self.presets)}")


def _model(name: str, entry: dict) -> RealSenseModel:
    default = entry["default"]
    return RealSenseModel(
        name=name, product=entry["product"], product_line=entry["product_line"], source=entry["source"],
        depth_unit_m=float(entry["depth_unit_m"]), color_sensor=entry["color_sensor"],
        color_distortion=entry["color_distortion"], presets=tuple(entry["presets"]),
        default=Stream(_size(default["color"]), _size(default["depth"]), int(default["fps"])),
        depth_modes={_size(k): tuple(v) for k, v in entry["depth_modes"].items()},
        color_modes={_size(k): tuple(v) for k, v in entry["color_modes"].items()},
        min_range_table=tuple(sorted((int(h), float(m)) for h, m in entry["min_range_m"].items())),
    )


@functools.cache
def models() -> dict[str, RealSenseModel]:
    """Every model of the table, by name (`d415`, ...)."""
    table = read_toml(TABLE, "the RealSense model table", CameraError, "reinstall axisloop")
    return {name: _model(name, entry) for name, entry in table.items()}


def model_named(name: str) -> RealSenseModel:
    """The model `name`; CameraError listing the known ones."""
    found = models().get(name)
    if found is None:
        raise CameraError(f"unknown RealSense model {name!r}: choose one of {', '.join(models())}, or realsense for "
                          "any RealSense")
    return found


def model_of(product: str | None) -> RealSenseModel | None:
    """The model of a device reporting the product name `product` (`camera_info.name`): the entry whose product
    name it starts with ("Intel RealSense D435I", a D435 with an IMU, is a d435); None for a RealSense the table
    does not hold."""
    return next((m for m in models().values() if product and product.startswith(m.product)), None)
