"""A live Intel RealSense camera of any model: aligned colour + depth from a background reader, with field-failure
handling. The model (`RealSenseConfig.model`, or the connected camera's) sets the streams' defaults and the
minimum range (drivers/camera/realsense_models.toml).

A read that times out is retried `config.retries` times; then the camera is hardware-reset and
reconnected and read again; if it still delivers nothing (or does not come back, e.g. unplugged), the
camera is released and one CameraError says what to check. Timestamps and indices keep increasing
across a reconnect.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

import pyrealsense2 as rs

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.realsense_config import RealSenseConfig
from drivers.camera.realsense_device import UsbLink
from drivers.camera.realsense_models import RealSenseModel, size_text
from drivers.camera.realsense_reader import LatestFrameReader
from drivers.camera.realsense_stream import RealSenseStream
from drivers.errors import CameraError


class DeviceLink(Protocol):
    """Where a RealSenseCamera's pipeline comes from (`UsbLink` for a USB camera); `model` is the camera's entry
    of the model table (None: one it does not hold), known once `pipeline_config` chose the device."""

    name: str
    model: RealSenseModel | None

    def pipeline_config(self) -> rs.config: ...

    def prepare(self, device: rs.device) -> None: ...

    def reset(self) -> None: ...


class RealSenseCamera(Camera):
    """A RealSense camera streaming `config` (default: its model's resolutions and rate) from `link` (default:
    USB)."""

    def __init__(self, config: RealSenseConfig | None = None, link: DeviceLink | None = None) -> None:
        self.config = config or RealSenseConfig()
        self.link: DeviceLink = link or UsbLink(self.config)
        self._stream: RealSenseStream | None = None
        self._reader: LatestFrameReader | None = None
        self._last: Frame | None = None
        self._t_offset, self._index_offset = 0.0, 0
        self._fps: int | None = None  # the stream's, once connected
        self.resets = 0

    @property
    def intrinsics(self) -> Intrinsics:
        return self._connected().intrinsics

    @property
    def serial(self) -> str | None:
        """The device's serial number (known once connected; used to find its calibration)."""
        return getattr(self.link, "serial", None)

    @property
    def depth_scale(self) -> float:
        """Metres per depth unit, read from the device."""
        return self._connected().depth_scale

    @property
    def min_range_m(self) -> float | None:
        """The nearest depth the camera measures at its depth resolution (its model's, from the datasheet); None for
        a RealSense the model table does not hold."""
        stream = self._connected()
        return None if self.link.model is None else self.link.model.min_range_m(stream.depth_size[1])

    def _connected(self) -> RealSenseStream:
        if self._stream is None:
            raise CameraError(f"{self.link.name} is not connected: use `with camera:` or call connect() first")
        return self._stream

    def connect(self) -> None:
        if self._stream is not None:
            return
        c = self.config
        try:
            stream = RealSenseStream(self.link.pipeline_config(), c.filters)
        except RuntimeError as exc:
            raise CameraError(
                f"{self.link.name}: could not start {self._asked()} ({exc}); check the profiles in `deploy cameras "
                "list` and that no other program uses the camera"
            ) from None
        try:
            self.link.prepare(stream.device)
            _warm_up(stream, c.warmup_frames, c.frame_timeout_s)
        except BaseException:
            stream.stop()
            raise
        self._stream, self._fps = stream, stream.fps
        self._reader = LatestFrameReader(stream.poll, stream.to_frame)

    def _asked(self) -> str:
        s = self.config.stream(self.link.model)
        return f"colour {size_text(s.color)} + depth {size_text(s.depth)} at {s.fps} fps"

    def disconnect(self) -> None:
        if self._reader is not None:
            self._reader.stop()
            self._reader = None
        if self._stream is not None:
            self._stream.stop()
            self._stream = None

    def read(self, timeout_s: float | None = None) -> Frame:
        """The newest frame, waiting up to `timeout_s` (default config.frame_timeout_s) per attempt."""
        timeout_s = self.config.frame_timeout_s if timeout_s is None else timeout_s
        self.connect()
        frame, cause = self._attempts(timeout_s)
        if frame is None:
            try:
                self._reconnect()
            except CameraError as exc:
                self.disconnect()
                raise CameraError(f"{self.link.name} stopped delivering frames ({cause}); {exc}") from None
            frame, cause = self._attempts(timeout_s)
        if frame is None:
            self.disconnect()
            raise CameraError(
                f"{self.link.name} delivered no frame within {timeout_s:g} s, {self.config.retries} retries and a "
                f"hardware reset ({cause}); check the USB 3 cable and port, and that no other program uses the "
                "camera, then run again"
            )
        frame = replace(frame, t=frame.t + self._t_offset, index=frame.index + self._index_offset)
        self._last = frame
        return frame

    def _attempts(self, timeout_s: float) -> tuple[Frame | None, str]:
        """Up to 1 + retries waits for a frame; (None, cause) if none came."""
        for _ in range(1 + self.config.retries):
            try:
                frame = self._reader.read(timeout_s)
            except RuntimeError as exc:  # librealsense, in the reader thread: the device went away
                return None, str(exc)
            if frame is not None:
                return frame, ""
        return None, f"no frame within {timeout_s:g} s"

    def _reconnect(self) -> None:
        """Hardware reset, then a new pipeline whose frames continue this one's timeline."""
        self.disconnect()
        self.link.reset()
        self.resets += 1
        if self._last is not None:
            self._t_offset = self._last.t + 1.0 / self._fps
            self._index_offset = self._last.index + 1
        self.connect()


def _warm_up(stream: RealSenseStream, frames: int, timeout_s: float) -> None:
    """Drop the first `frames` whole framesets while auto exposure settles. Skipped partial framesets do not count
    (at most as many again are polled); a silent camera ends the wait early and is handled by read()."""
    dropped = 0
    for _ in range(2 * frames):
        if dropped == frames:
            return
        if stream.poll(timeout_s) is not None:
            dropped += 1
        elif stream.timed_out:
            return

