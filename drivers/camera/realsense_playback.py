"""Replay of RealSense recordings (`.bag`, ROS1, from older SDKs and RealSense Viewer; `.db3`, rosbag2, which
pyrealsense2 2.59 writes) through the same pipeline code as the live D415, frame by frame, not in real time."""

from __future__ import annotations

from pathlib import Path

import pyrealsense2 as rs

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.realsense_config import FilterConfig
from drivers.camera.realsense_stream import RealSenseStream
from drivers.errors import RecordingError

SUFFIXES = (".bag", ".db3")
END_DRAIN_S = 0.5


class RealSenseReplayCamera(Camera):
    """Plays `path` once, every recorded frame in order; RecordingError at the end.

    filters: post-processing as for the live camera (default none: the recording's raw depth).
    """

    def __init__(self, path: str | Path, filters: FilterConfig | None = None) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() not in SUFFIXES:
            raise RecordingError(f"{self.path}: not a RealSense recording; expected a .bag or .db3 file")
        if not self.path.is_file():
            raise RecordingError(f"RealSense recording {self.path} not found; check the path")
        self.filters = filters or FilterConfig.none()
        self._stream: RealSenseStream | None = None
        self.frames_read = 0

    @property
    def intrinsics(self) -> Intrinsics:
        self.connect()
        return self._stream.intrinsics

    @property
    def depth_scale(self) -> float:
        """Metres per depth unit of the recording."""
        self.connect()
        return self._stream.depth_scale

    def connect(self) -> None:
        if self._stream is not None:
            return
        config = rs.config()
        try:
            config.enable_device_from_file(str(self.path), repeat_playback=False)
            self._stream = RealSenseStream(config, self.filters)
        except RuntimeError as exc:
            raise RecordingError(
                f"cannot play RealSense recording {self.path}: {exc}; the file is truncated, corrupt or lacks a "
                "colour and a depth stream: record it again (RealSense Viewer or `deploy record`)"
            ) from None
        self.frames_read = 0

    def disconnect(self) -> None:
        if self._stream is not None:
            self._stream.stop()
            self._stream = None

    def read(self, timeout_s: float = 2.0) -> Frame:
        """The next recorded frame; RecordingError at the end of the file. Once the file is read to its end,
        one more wait of END_DRAIN_S lets a last frameset still in the syncer through (on a loaded machine the
        playback stopped before it came, about once in 60 replays of a 2-frame file)."""
        self.connect()
        stream = self._stream
        draining = False
        while True:
            frame = stream.poll(END_DRAIN_S if draining else min(timeout_s, 0.2))
            if frame is not None:
                self.frames_read += 1
                return frame
            if not stream.timed_out:
                continue  # a skipped partial frameset
            if not draining and stream.playback.current_status() == rs.playback_status.stopped:
                draining = True
                continue
            if draining or timeout_s <= 0.2:
                raise RecordingError(f"end of RealSense recording {self.path} after {self.frames_read} frames")
            timeout_s -= 0.2
