"""Synthetic RealSense recordings for the tests: a software device with a depth and a colour sensor,
recorded to .db3 by librealsense's own recorder (no camera needed)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyrealsense2 as rs

SERIAL = "000111222333"
SQUARE_ROWS, SQUARE_COLS = (19.5, 27.5), (23.5, 31.5)  # the 0.8 m square of `scene`, in depth pixel coordinates


@dataclass
class Synthetic:
    """What the recording holds: depth (H, W) uint16 units and colour (H, W, 3) RGB per frame."""

    width: int = 64
    height: int = 48
    depth_fx: float = 60.0
    color_fx: float = 50.0
    depth_units_m: float = 0.0001
    baseline_m: float = 0.015  # depth -> colour translation along x
    period_ms: float = 1000.0 / 30
    t0_ms: float = 5000.0
    depth: list[np.ndarray] = field(default_factory=list)
    color: list[np.ndarray] = field(default_factory=list)

    def intrinsics(self, fx: float) -> rs.intrinsics:
        i = rs.intrinsics()
        i.width, i.height = self.width, self.height
        i.ppx, i.ppy = (self.width - 1) / 2, (self.height - 1) / 2
        i.fx = i.fy = fx
        i.model, i.coeffs = rs.distortion.none, [0.0] * 5
        return i


def scene(n: int, **kwargs) -> Synthetic:
    """`n` frames: a plane 1.0 m away with a 0.8 m square (depth pixels rows 20:28, columns 24:32);
    colour red = frame number, green = column, blue = row."""
    s = Synthetic(**kwargs)
    rows, cols = np.mgrid[0:s.height, 0:s.width]
    for k in range(n):
        depth_m = np.full((s.height, s.width), 1.0)
        depth_m[20:28, 24:32] = 0.8
        s.depth.append(np.round(depth_m / s.depth_units_m).astype(np.uint16))
        s.color.append(np.stack([np.full_like(rows, k), cols, rows], axis=-1).astype(np.uint8))
    return s


def write_db3(path: Path, s: Synthetic, color_format: rs.format = rs.format.rgb8, color_lag: int = 0) -> Path:
    """Record `s` to `path` (.db3) through rs.software_device + rs.recorder; colour frame k follows depth frame
    k + `color_lag` in the file; a frame that is None in `s` is not recorded (the camera dropped it)."""
    device = rs.software_device()
    for info, value in ((rs.camera_info.serial_number, SERIAL), (rs.camera_info.name, "Intel RealSense D415"),
                        (rs.camera_info.firmware_version, "5.16.0.1"), (rs.camera_info.usb_type_descriptor, "3.2")):
        device.register_info(info, value)
    depth_sensor, color_sensor = device.add_sensor("Stereo Module"), device.add_sensor("RGB Camera")
    depth_sensor.add_read_only_option(rs.option.depth_units, s.depth_units_m)
    profiles = []
    for uid, (sensor, kind, fmt, bpp, fx) in enumerate((
        (depth_sensor, rs.stream.depth, rs.format.z16, 2, s.depth_fx),
        (color_sensor, rs.stream.color, color_format, 3, s.color_fx),
    )):
        vs = rs.video_stream()
        vs.type, vs.index, vs.uid, vs.width, vs.height = kind, 0, uid, s.width, s.height
        vs.fps, vs.bpp, vs.fmt, vs.intrinsics = round(1000 / s.period_ms), bpp, fmt, s.intrinsics(fx)
        profiles.append(sensor.add_video_stream(vs))
    extrinsics = rs.extrinsics()
    extrinsics.rotation, extrinsics.translation = [1, 0, 0, 0, 1, 0, 0, 0, 1], [s.baseline_m, 0.0, 0.0]
    profiles[0].register_extrinsics_to(profiles[1], extrinsics)
    recorder = rs.recorder(str(path), device)
    for sensor, profile in zip((depth_sensor, color_sensor), profiles, strict=True):
        sensor.open(profile)
        sensor.start(lambda _frame: None)
    # colour frame k follows depth frame k + color_lag in the file (a colour stream that arrives later)
    order = sorted([(k, 0) for k in range(len(s.depth))] + [(k, 1) for k in range(len(s.color))],
                   key=lambda e: (e[0] + color_lag * e[1], e[1]))
    for k, which in order:
        sensor, profile, bpp = ((depth_sensor, profiles[0], 2), (color_sensor, profiles[1], 3))[which]
        image = (s.depth, s.color)[which][k]
        if image is None:  # a frame the camera dropped
            continue
        if which == 1 and color_format == rs.format.bgr8:
            image = image[..., ::-1]
        frame = rs.software_video_frame()
        frame.pixels, frame.bpp, frame.stride = np.ascontiguousarray(image), bpp, s.width * bpp
        frame.timestamp, frame.frame_number = s.t0_ms + k * s.period_ms, 100 + k
        frame.domain, frame.profile = rs.timestamp_domain.hardware_clock, profile.as_video_stream_profile()
        sensor.on_video_frame(frame)
    for sensor in (depth_sensor, color_sensor):
        sensor.stop()
        sensor.close()
    recorder.pause()
    del recorder, device
    return path


def expected_depth(s: Synthetic) -> np.ndarray:
    """What the colour camera sees of `scene` (the square at 0.8 m in front of the plane at 1.0 m), ray-cast
    through each colour pixel's centre; 0 where it sees a surface the depth camera did not (the plane behind
    the square, or beyond the depth camera's field of view)."""
    rows, cols = np.mgrid[0:s.height, 0:s.width].astype(float)
    c = (s.width - 1) / 2, (s.height - 1) / 2
    a, b = (cols - c[0]) / s.color_fx, (rows - c[1]) / s.color_fx  # ray (a, b, 1) from the colour centre

    def depth_pixel(z: float) -> tuple[np.ndarray, np.ndarray]:  # where the ray meets depth z, in depth pixels
        return (a * z - s.baseline_m) / z * s.depth_fx + c[0], b * s.depth_fx + c[1]

    def inside(x, y, rows_, cols_):
        return (y >= rows_[0]) & (y < rows_[1]) & (x >= cols_[0]) & (x < cols_[1])

    out = np.zeros((s.height, s.width))
    square = inside(*depth_pixel(0.8), SQUARE_ROWS, SQUARE_COLS)
    x, y = depth_pixel(1.0)
    seen = inside(x, y, (-0.5, s.height - 0.5), (-0.5, s.width - 0.5)) & ~inside(x, y, SQUARE_ROWS, SQUARE_COLS)
    out[seen] = 1.0
    out[square] = 0.8
    return out
