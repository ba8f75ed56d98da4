"""RealSense devices on USB: discovery, opening by serial and model, sensor settings, hardware reset and reconnect."""

from __future__ import annotations

import time

import pyrealsense2 as rs

from drivers.camera.realsense_config import ANY_STREAM, RealSenseConfig
from drivers.camera.realsense_models import RealSenseModel, Stream, model_named, model_of, size_text
from drivers.camera.realsense_stream import intrinsics_of
from drivers.errors import CameraError

_PRESET_ENUMS = {"D400": rs.rs400_visual_preset, "L500": rs.l500_visual_preset}  # by the model's product line


def _info(device: rs.device, field: rs.camera_info) -> str | None:
    return device.get_info(field) if device.supports(field) else None


def color_sensor(device: rs.device) -> rs.sensor:
    """The sensor that gives `device`'s colour stream: its colour camera, or on a camera without one (a D405) the
    depth module, whose own RGB stream it is. RuntimeError when the device streams no colour."""
    for sensor in device.query_sensors():
        if any(p.stream_type() == rs.stream.color for p in sensor.get_stream_profiles()):
            return sensor
    raise RuntimeError("the device has no colour stream")


def describe_device(device: rs.device) -> dict:
    """What `deploy cameras list` shows of a device: serial, product name, model (a name of the model table, None
    for one it does not hold), firmware, USB type, the sensor giving colour, the depth unit, the colour intrinsics
    (lens model included) and the minimum range at the model's default resolution (`stream`), and the video
    profiles ("Depth 640x480 Z16 @30")."""
    name = _info(device, rs.camera_info.name)
    model = model_of(name)
    stream = model.default if model is not None else ANY_STREAM
    profiles = [p.as_video_stream_profile() for sensor in device.query_sensors()
                for p in sensor.get_stream_profiles() if p.is_video_stream_profile()]
    colour = [p for p in profiles if p.stream_type() == rs.stream.color]
    chosen = next((p for p in colour if (p.width(), p.height()) == stream.color),
                  max(colour, key=lambda p: p.width() * p.height(), default=None))
    depth_sensors = [sensor for sensor in device.query_sensors() if sensor.is_depth_sensor()]
    return {
        "serial": _info(device, rs.camera_info.serial_number),
        "name": name,
        "model": None if model is None else model.name,
        "firmware": _info(device, rs.camera_info.firmware_version),
        "usb_type": _info(device, rs.camera_info.usb_type_descriptor),
        "color_sensor": color_sensor(device).get_info(rs.camera_info.name) if colour else None,
        "depth_scale": float(depth_sensors[0].as_depth_sensor().get_depth_scale()) if depth_sensors else None,
        "intrinsics": None if chosen is None else intrinsics_of(chosen).to_dict(),
        "min_range_m": None if model is None else model.min_range_m(stream.depth[1]),
        "stream": {"color": size_text(stream.color), "depth": size_text(stream.depth), "fps": stream.fps},
        "profiles": sorted({f"{p.stream_name()} {p.width()}x{p.height()} {p.format().name.upper()} @{p.fps()}"
                            for p in profiles}),
    }


def list_devices() -> list[dict]:
    """Every connected RealSense camera, described; [] when none is connected."""
    return [describe_device(d) for d in rs.context().query_devices()]


def connected() -> dict[str, str]:
    """The connected RealSense cameras: serial -> product name."""
    return {d.get_info(rs.camera_info.serial_number): d.get_info(rs.camera_info.name)
            for d in rs.context().query_devices()}


class UsbLink:
    """The USB camera a `RealSenseCamera` streams from: which device to open (by serial, and of the config's model),
    its model and stream, its settings, its reset."""

    def __init__(self, config: RealSenseConfig) -> None:
        self.config = config
        self.serial = config.serial
        self.model: RealSenseModel | None = model_named(config.model) if config.model else None
        self.stream: Stream | None = None  # known once the device is chosen

    @property
    def name(self) -> str:
        label = self.model.name.upper() if self.model is not None else self.config.label
        return f"{label} {self.serial}" if self.serial else label

    def pipeline_config(self) -> rs.config:
        """Select the device (the only one, of the config's model, when no serial is set) and its colour + depth
        streams at its model's resolutions."""
        product = self._choose(connected())
        self.model = model_of(product) or self.model
        self.stream = s = self.config.stream(self.model)
        config = rs.config()
        config.enable_device(self.serial)
        config.enable_stream(rs.stream.depth, *s.depth, rs.format.z16, s.fps)
        config.enable_stream(rs.stream.color, *s.color, rs.format.rgb8, s.fps)
        return config

    def _choose(self, devices: dict[str, str]) -> str:
        """The product name of the device to open (its serial set), from the connected `devices`."""
        spec = self.config.model or "realsense"
        listing = ", ".join(f"{serial} ({product})" for serial, product in devices.items())
        if not devices:
            raise CameraError("no RealSense camera is connected; plug it into a USB 3 port and check "
                              "`deploy cameras list`")
        wanted = self.model
        if self.serial is not None:
            if self.serial not in devices:
                raise CameraError(f"no RealSense camera with serial {self.serial}; connected: {listing}; check the "
                                  "serial with `deploy cameras list`")
            found = model_of(devices[self.serial])
            if wanted is not None and found is not wanted:
                use = found.name if found is not None else "realsense"
                raise CameraError(f"camera {self.serial} is an {devices[self.serial]}, not a {wanted.name.upper()}: "
                                  f"use --camera {use}:{self.serial}")
            return devices[self.serial]
        candidates = [s for s, product in devices.items() if wanted is None or model_of(product) is wanted]
        if not candidates:
            raise CameraError(f"no {wanted.name.upper()} is connected (connected: {listing}); use --camera realsense "
                              "or the connected camera's model")
        if len(candidates) > 1:
            raise CameraError(f"{len(candidates)} RealSense cameras are connected ({listing}); choose one with "
                              f"--camera {spec}:SERIAL")
        self.serial = candidates[0]
        return devices[self.serial]

    def prepare(self, device: rs.device) -> None:
        """Apply the visual preset and exposure settings to the started device."""
        c = self.config
        depth, colour = device.first_depth_sensor(), color_sensor(device)
        if c.visual_preset is not None:
            _set(depth, rs.option.visual_preset, self._preset_value(c.visual_preset), self.name)
        if colour.get_info(rs.camera_info.name) == depth.get_info(rs.camera_info.name):
            if c.color_exposure is not None:
                raise CameraError(f"{self.name}: its colour comes from the depth module, whose exposure is "
                                  "depth_exposure_us: drop color_exposure")
            exposures = ((depth, c.depth_exposure_us),)
        else:
            exposures = ((depth, c.depth_exposure_us), (colour, c.color_exposure))
        for sensor, exposure in exposures:
            if exposure is None:
                _set(sensor, rs.option.enable_auto_exposure, 1.0, self.name)
            else:
                _set(sensor, rs.option.enable_auto_exposure, 0.0, self.name)
                _set(sensor, rs.option.exposure, float(exposure), self.name)

    def _preset_value(self, preset: str) -> float:
        """librealsense's value of visual preset `preset` in the enum of the camera's product line (either, for a
        camera the table does not hold: the device's option range refuses one that is not its own)."""
        lines = [self.model.product_line] if self.model is not None else list(_PRESET_ENUMS)
        for line in lines:
            if hasattr(_PRESET_ENUMS[line], preset):
                return float(getattr(_PRESET_ENUMS[line], preset))
        raise CameraError(f"{self.name}: unknown visual preset {preset!r}")

    def reset(self) -> None:
        """Hardware-reset the camera and wait until it is enumerated again; CameraError if it does not
        come back within `reset_wait_s` (unplugged)."""
        for device in rs.context().query_devices():
            if device.get_info(rs.camera_info.serial_number) == self.serial:
                device.hardware_reset()
                time.sleep(1.0)  # the old device disappears first
                break
        deadline = time.monotonic() + self.config.reset_wait_s
        while time.monotonic() < deadline:
            if self.serial in connected():
                return
            time.sleep(0.2)
        raise CameraError(f"{self.name} did not come back within {self.config.reset_wait_s:.0f} s after a hardware "
                          "reset; check the USB cable (USB 3 port) and power, then run again")


def _set(sensor: rs.sensor, option: rs.option, value: float, name: str) -> None:
    if not sensor.supports(option):
        raise CameraError(f"{name}: the {sensor.get_info(rs.camera_info.name)} does not support {option}; "
                          "remove the setting")
    r = sensor.get_option_range(option)
    if not r.min <= value <= r.max:
        raise CameraError(f"{name}: {option} = {value:g} is outside the device's range [{r.min:g}, {r.max:g}]")
    sensor.set_option(option, value)
