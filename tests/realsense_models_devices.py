"""Software RealSense devices with each model's stream profiles, recorded to .db3 by librealsense's own recorder.

Each `ModelDevice` is what that model's camera reports at its default resolution: product name, the sensors (a D405
has no colour camera: its colour stream is on the depth module, "Stereo Module"), the depth unit, and the depth and
colour intrinsics with the lens model and coefficients librealsense reports (coefficients of the size units show;
the D455's and L515's colour lenses have non-zero ones). The scene is a plane with a nearer square near the image's
corner, where a lens's distortion moves pixels most.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyrealsense2 as rs

SERIAL = "123456789012"
PERIOD_MS = 1000.0 / 30


@dataclass(frozen=True)
class Lens:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    model: rs.distortion = rs.distortion.none
    coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def rs(self) -> rs.intrinsics:
        i = rs.intrinsics()
        i.width, i.height, i.fx, i.fy, i.ppx, i.ppy = self.width, self.height, self.fx, self.fy, self.cx, self.cy
        i.model, i.coeffs = self.model, list(self.coeffs)
        return i


@dataclass(frozen=True)
class ModelDevice:
    name: str  # the model table's
    product: str
    color_sensor: str  # "RGB Camera", or "Stereo Module" for colour from the depth module
    depth_unit_m: float
    depth: Lens
    color: Lens
    baseline_m: float  # depth -> colour translation along x
    plane_m: float  # the plane's distance; the square stands at 0.9 of it

    @property
    def square_m(self) -> float:
        return round(0.9 * self.plane_m / self.depth_unit_m) * self.depth_unit_m


INVERSE_BC, BROWN = rs.distortion.inverse_brown_conrady, rs.distortion.brown_conrady
DEVICES = {d.name: d for d in (
    ModelDevice("d415", "Intel RealSense D415", "RGB Camera", 0.001,
                Lens(640, 480, 592.9, 592.9, 321.1, 238.4, BROWN),
                Lens(640, 480, 615.8, 616.1, 318.4, 243.2, INVERSE_BC), 0.0147, 1.0),
    ModelDevice("d435", "Intel RealSense D435", "RGB Camera", 0.001,
                Lens(848, 480, 421.6, 421.6, 424.9, 236.7, BROWN),
                Lens(848, 480, 611.4, 611.7, 423.5, 245.1, INVERSE_BC), 0.0149, 1.0),
    ModelDevice("d455", "Intel RealSense D455", "RGB Camera", 0.001,
                Lens(848, 480, 426.2, 426.2, 423.6, 240.3, BROWN),
                Lens(848, 480, 424.7, 424.1, 421.3, 240.8, INVERSE_BC, (-0.0553, 0.0667, -0.0007, 0.0006, -0.0212)),
                0.0591, 1.0),
    ModelDevice("d405", "Intel RealSense D405", "Stereo Module", 0.0001,
                Lens(848, 480, 433.5, 433.5, 424.8, 241.9, BROWN),
                Lens(848, 480, 436.1, 435.4, 426.9, 243.5, INVERSE_BC, (-0.0541, 0.0592, 0.0004, 0.0011, -0.0187)),
                0.0, 0.2003),
    ModelDevice("l515", "Intel RealSense L515", "RGB Camera", 0.00025,
                Lens(1024, 768, 730.9, 731.2, 511.2, 393.6),
                Lens(1280, 720, 904.5, 904.9, 646.1, 361.7, INVERSE_BC, (0.1711, -0.5235, -0.0009, 0.0004, 0.4785)),
                0.0141, 1.5),
)}


def square_px(lens: Lens) -> tuple[slice, slice]:
    """Rows and columns of the nearer square in the depth image: near the bottom-right corner."""
    rows, cols = (int(0.70 * lens.height), int(0.88 * lens.height)), (int(0.74 * lens.width), int(0.90 * lens.width))
    return slice(*rows), slice(*cols)


def square_bounds(device: ModelDevice) -> tuple[np.ndarray, np.ndarray]:
    """The square's (x, y) extent in the depth camera's frame (m): its depth pixels' outer edges at its distance."""
    d, (rows, cols) = device.depth, square_px(device.depth)
    z = device.square_m
    lo = np.array([(cols.start - 0.5 - d.cx) / d.fx, (rows.start - 0.5 - d.cy) / d.fy]) * z
    hi = np.array([(cols.stop - 0.5 - d.cx) / d.fx, (rows.stop - 0.5 - d.cy) / d.fy]) * z
    return lo, hi


def depth_image(device: ModelDevice) -> np.ndarray:
    """The depth frame in the device's units: the plane, and the square at 0.9 of its distance."""
    d = device.depth
    units = np.full((d.height, d.width), round(device.plane_m / device.depth_unit_m), np.uint16)
    units[square_px(d)] = round(device.square_m / device.depth_unit_m)
    return units


def write_model_db3(path: Path, device: ModelDevice, frames: int = 3) -> Path:
    """Record `frames` frames of the scene from a software device with `device`'s sensors and profiles."""
    dev = rs.software_device()
    for info, value in ((rs.camera_info.serial_number, SERIAL), (rs.camera_info.name, device.product),
                        (rs.camera_info.firmware_version, "5.16.0.1"), (rs.camera_info.usb_type_descriptor, "3.2")):
        dev.register_info(info, value)
    depth_sensor = dev.add_sensor("Stereo Module")
    color_sensor = depth_sensor if device.color_sensor == "Stereo Module" else dev.add_sensor(device.color_sensor)
    depth_sensor.add_read_only_option(rs.option.depth_units, device.depth_unit_m)
    profiles = []
    for uid, (sensor, kind, fmt, bpp, lens) in enumerate((
        (depth_sensor, rs.stream.depth, rs.format.z16, 2, device.depth),
        (color_sensor, rs.stream.color, rs.format.rgb8, 3, device.color),
    )):
        vs = rs.video_stream()
        vs.type, vs.index, vs.uid, vs.width, vs.height = kind, 0, uid, lens.width, lens.height
        vs.fps, vs.bpp, vs.fmt, vs.intrinsics = 30, bpp, fmt, lens.rs()
        profiles.append(sensor.add_video_stream(vs))
    extrinsics = rs.extrinsics()
    extrinsics.rotation, extrinsics.translation = [1, 0, 0, 0, 1, 0, 0, 0, 1], [device.baseline_m, 0.0, 0.0]
    profiles[0].register_extrinsics_to(profiles[1], extrinsics)
    recorder = rs.recorder(str(path), dev)
    sensors = [depth_sensor] if color_sensor is depth_sensor else [depth_sensor, color_sensor]
    if color_sensor is depth_sensor:
        depth_sensor.open(profiles)
    else:
        for sensor, profile in zip(sensors, profiles, strict=True):
            sensor.open(profile)
    for sensor in sensors:
        sensor.start(lambda _frame: None)
    depth = depth_image(device)
    c = device.color
    rows, cols = np.mgrid[0:c.height, 0:c.width]
    for k in range(frames):
        color = np.stack([np.full_like(rows, k), cols % 256, rows % 256], axis=-1).astype(np.uint8)
        for sensor, profile, image, bpp in ((depth_sensor, profiles[0], depth, 2),
                                            (color_sensor, profiles[1], color, 3)):
            frame = rs.software_video_frame()
            frame.pixels, frame.bpp, frame.stride = np.ascontiguousarray(image), bpp, image.shape[1] * bpp
            frame.timestamp, frame.frame_number = 1000.0 + k * PERIOD_MS, 100 + k
            frame.domain, frame.profile = rs.timestamp_domain.hardware_clock, profile.as_video_stream_profile()
            sensor.on_video_frame(frame)
    for sensor in sensors:
        sensor.stop()
        sensor.close()
    recorder.pause()
    del recorder, dev
    return path
