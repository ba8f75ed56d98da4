"""RealSense devices on USB: discovery, opening by serial, sensor settings, hardware reset and reconnect."""

from __future__ import annotations

import time

import pyrealsense2 as rs

from drivers.camera.realsense_config import RealSenseConfig
from drivers.errors import CameraError

_PRESETS = {name: getattr(rs.rs400_visual_preset, name) for name in (
    "custom", "default", "hand", "high_accuracy", "high_density", "medium_density")}


def _info(device: rs.device, field: rs.camera_info) -> str | None:
    return device.get_info(field) if device.supports(field) else None


def describe_device(device: rs.device) -> dict:
    """Serial, name, firmware, USB type and the video profiles ("Depth 640x480 Z16 @30") of a device."""
    profiles = sorted({
        f"{p.stream_name()} {v.width()}x{v.height()} {p.format().name.upper()} @{p.fps()}"
        for sensor in device.query_sensors() for p in sensor.get_stream_profiles()
        if p.is_video_stream_profile() and (v := p.as_video_stream_profile())
    })
    return {
        "serial": _info(device, rs.camera_info.serial_number),
        "name": _info(device, rs.camera_info.name),
        "firmware": _info(device, rs.camera_info.firmware_version),
        "usb_type": _info(device, rs.camera_info.usb_type_descriptor),
        "profiles": profiles,
    }


def list_devices() -> list[dict]:
    """Every connected RealSense camera, described; [] when none is connected."""
    return [describe_device(d) for d in rs.context().query_devices()]


def connected_serials() -> list[str]:
    return [d.get_info(rs.camera_info.serial_number) for d in rs.context().query_devices()]


class UsbLink:
    """The USB camera a `D415Camera` streams from: which device to open, its settings, its reset."""

    def __init__(self, config: RealSenseConfig) -> None:
        self.config = config
        self.serial = config.serial

    @property
    def name(self) -> str:
        return f"D415 {self.serial}" if self.serial else "D415"

    def pipeline_config(self) -> rs.config:
        """Select the device (the only one when no serial is set) and its colour + depth streams."""
        serials = connected_serials()
        if not serials:
            raise CameraError("no RealSense camera is connected; plug the D415 into a USB 3 port "
                              "and check `deploy cameras list`")
        if self.serial is None:
            if len(serials) > 1:
                raise CameraError(f"{len(serials)} RealSense cameras are connected ({', '.join(serials)}); "
                                  "choose one with --camera d415:SERIAL")
            self.serial = serials[0]
        elif self.serial not in serials:
            raise CameraError(f"no RealSense camera with serial {self.serial}; connected: {', '.join(serials)}; "
                              "check the serial with `deploy cameras list`")
        c = self.config
        config = rs.config()
        config.enable_device(self.serial)
        config.enable_stream(rs.stream.depth, c.width, c.height, rs.format.z16, c.fps)
        config.enable_stream(rs.stream.color, c.width, c.height, rs.format.rgb8, c.fps)
        return config

    def prepare(self, device: rs.device) -> None:
        """Apply the visual preset and exposure settings to the started device."""
        c = self.config
        depth = device.first_depth_sensor()
        if c.visual_preset is not None:
            _set(depth, rs.option.visual_preset, float(_PRESETS[c.visual_preset]), self.name)
        for sensor, exposure in ((depth, c.depth_exposure_us), (device.first_color_sensor(), c.color_exposure)):
            if exposure is None:
                _set(sensor, rs.option.enable_auto_exposure, 1.0, self.name)
            else:
                _set(sensor, rs.option.enable_auto_exposure, 0.0, self.name)
                _set(sensor, rs.option.exposure, float(exposure), self.name)

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
            if self.serial in connected_serials():
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
