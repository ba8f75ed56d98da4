"""Replay of RealSense recordings (`.bag`, ROS1, from older SDKs and RealSense Viewer; `.db3`, rosbag2, which
pyrealsense2 2.59 writes): every recorded colour + depth pair once, in order, not in real time, however slow the
reader or loaded the machine.

Each stream is played by a playback device of its own into a queue of QUEUE frames that the player waits on while
it is full (not real time: librealsense drops nothing), and colour and depth are paired here by timestamp.
librealsense's pipeline is not used for recordings: its syncer learns the streams from their first frames, so when
the depth frames reached it before the first colour frame (2 replays in 100 of an 8-frame recording here) it paired
every colour frame with the last depth frame and the replay kept 1 frame of 8; and of two sensors on one playback,
the one started second lost the frames read before it started. The recording's index (read with rosbags) says how
many frames each stream holds, and `lost_frames()` says when fewer were played.
"""

from __future__ import annotations

import re
import time
import weakref
from collections import deque
from pathlib import Path

import numpy as np
import pyrealsense2 as rs

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.depth_align import DepthAligner
from drivers.camera.realsense_config import FilterConfig
from drivers.camera.realsense_models import model_of
from drivers.camera.realsense_stream import build_filters, intrinsics_of, to_rgb
from drivers.errors import CameraError, RecordingError

SUFFIXES = (".bag", ".db3")
QUEUE = 8  # frames of one stream waiting to be read; librealsense's frame pool holds 16 unread frames a stream
WAIT_MS = 10  # one wait for a frame (kept short: pyrealsense2 may hold the GIL meanwhile)
STALL_S = 30.0  # no frame for this long while a stream still plays: librealsense stalled
START_S = 10.0  # a stream whose frame count is unknown and that does not start playing for this long is empty
LATE_S = 1.0  # after a stream's playback stopped, how long frames its index holds that did not arrive are awaited
_COLOR_FORMATS = (rs.format.rgb8, rs.format.bgr8, rs.format.rgba8, rs.format.bgra8)
_TOPIC = re.compile(r"^/device_\d+/sensor_\d+/(?P<stream>[A-Za-z]+_\d+)/image/data(/|$)")


def recorded_frames(path: Path) -> dict[str, int] | None:
    """Frames per stream ("Depth_0", "Color_0", ...) that the recording's index lists (read with rosbags, no image
    decoded), or None when the index cannot be read."""
    try:
        if path.suffix.lower() == ".bag":
            from rosbags.rosbag1 import Reader
        else:
            from rosbags.rosbag2 import Reader
        reader = Reader(path)
        reader.open()
    except Exception:  # noqa: BLE001 - rosbags raises several types; librealsense judges the file itself
        return None
    try:
        counts: dict[str, int] = {}
        for connection in reader.connections:
            if (match := _TOPIC.match(connection.topic)) is not None:
                counts[match["stream"]] = counts.get(match["stream"], 0) + connection.msgcount
        return counts
    finally:
        reader.close()


class _StreamPlayer:
    """One stream (depth or colour) of a recording, played not in real time by a playback device of its own."""

    def __init__(self, path: Path, kind: rs.stream, recorded: dict[str, int] | None) -> None:
        self.device = rs.context().load_device(str(path))
        self.playback = self.device.as_playback()
        self.playback.set_real_time(False)
        found = [(s, p.as_video_stream_profile()) for s in self.device.query_sensors()
                 for p in s.get_stream_profiles() if p.stream_type() == kind and p.is_video_stream_profile()]
        if not found:
            raise RuntimeError(f"no {kind.name} stream")
        self.sensor, self.profile = found[0]
        self.name = f"{kind.name.capitalize()}_{self.profile.stream_index()}"
        self.expected = None if recorded is None else recorded.get(self.name)  # None: not known
        self.delivered = 0
        self._queue = rs.syncer(QUEUE)  # a C++ sink: librealsense never waits for Python (nor for the GIL)
        self._ahead: deque[rs.frame] = deque()
        self._last_ms: float | None = None
        self._started = False
        self.ended = False
        self.sensor.open(self.profile)
        try:
            self.sensor.start(self._queue)
        except RuntimeError:
            self.sensor.close()
            raise

    def peek(self, k: int = 0) -> rs.frame | None:
        """The k-th next frame, not taken; None past the end of the stream."""
        while len(self._ahead) <= k:
            frame = self._next()
            if frame is None:
                return None
            self._ahead.append(frame)
        return self._ahead[k]

    def take(self) -> rs.frame | None:
        """The next frame; None at the end of the stream."""
        frame = self.peek()
        if frame is not None:
            self._ahead.popleft()
        return frame

    def _next(self) -> rs.frame | None:
        """The next frame from librealsense, waiting as long as the playback plays; None at the end."""
        waited_since, stopped_since = time.monotonic(), None
        while not self.ended:
            frame = self._poll()
            if frame is None:
                now = time.monotonic()
                if self.playback.current_status() != rs.playback_status.stopped:
                    self._started, stopped_since = True, None
                    if now - waited_since > STALL_S:
                        raise CameraError(
                            f"RealSense recording {self.playback.file_name()}: no {self.name} frame for "
                            f"{STALL_S:g} s while the playback plays (after {self.delivered}); librealsense "
                            "stalled: run again")
                    continue
                stopped_since = now if stopped_since is None else stopped_since
                if not self._at_end(now - waited_since, now - stopped_since):
                    continue
                frame = self._poll()  # a frame queued just before the playback stopped
                if frame is None:
                    self.ended = True
                    return None
            self._started = True
            if self._last_ms is not None and frame.get_timestamp() <= self._last_ms:
                continue  # a frame played again (librealsense does after a seek; not seen here)
            self._last_ms = frame.get_timestamp()
            self.delivered += 1
            return frame
        return None

    def _at_end(self, waited_s: float, stopped_s: float) -> bool:
        """Whether a stopped playback has ended: it played what the file's index lists, or nothing more came for
        LATE_S after it stopped. One that has not started yet is waited for (STALL_S; START_S when the file's
        count is unknown)."""
        if self.expected == 0:
            return True
        if not self._started:
            return waited_s > (STALL_S if self.expected else START_S)
        return self.expected is None or self.delivered >= self.expected or stopped_s > LATE_S

    def _poll(self) -> rs.frame | None:
        ok, frames = self._queue.try_wait_for_frames(WAIT_MS)
        if not ok:
            return None
        frame = frames[0] if frames.size() else frames
        frame.keep()  # out of librealsense's frame pool, which would otherwise drop frames once 16 are held
        return frame

    def close(self) -> None:
        """Stop playing (idempotent). Stopped early, the player may wait for room in the queue: it is emptied
        until the pause is in effect."""
        try:
            if self.playback.current_status() == rs.playback_status.playing:
                self._empty()
                self.playback.pause()
                deadline = time.monotonic() + STALL_S
                while (self.playback.current_status() == rs.playback_status.playing
                       and time.monotonic() < deadline):
                    self._empty()
        except RuntimeError:
            pass
        finally:  # a sensor left started blocks librealsense's device destructor, and with it the process
            self._empty()
            for step in (self.sensor.stop, self.sensor.close):
                try:
                    step()
                except RuntimeError:
                    pass
            self._ahead.clear()

    def _empty(self) -> None:
        while self._queue.poll_for_frames():
            pass


class RealSenseReplayCamera(Camera):
    """Plays `path` once, every recorded colour + depth pair in order; RecordingError at the end.

    A colour and a depth frame pair up when their timestamps are within half a colour frame period (the closest
    ones when several are); a frame of either stream with no partner is counted in `unpaired` and skipped.
    filters: post-processing as for the live camera (default none: the recording's raw depth).
    """

    def __init__(self, path: str | Path, filters: FilterConfig | None = None) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() not in SUFFIXES:
            raise RecordingError(f"{self.path}: not a RealSense recording; expected a .bag or .db3 file")
        if not self.path.is_file():
            raise RecordingError(f"RealSense recording {self.path} not found; check the path")
        self.filters = filters or FilterConfig.none()
        self._depth: _StreamPlayer | None = None
        self._color: _StreamPlayer | None = None
        self.frames_read = 0
        self.recorded: dict[str, int | None] | None = None  # frames per stream the file's index lists (None: unknown)
        self.delivered = {"depth": 0, "color": 0}  # frames librealsense played, per stream
        self.unpaired = {"depth": 0, "color": 0}  # played frames that had no partner in the other stream

    @property
    def intrinsics(self) -> Intrinsics:
        self.connect()
        return self._intrinsics

    @property
    def depth_scale(self) -> float:
        """Metres per depth unit of the recording."""
        self.connect()
        return self._depth_scale

    @property
    def min_range_m(self) -> float | None:
        """The recorded camera's minimum range at the recording's depth resolution (its model's); None for a camera
        the model table does not hold."""
        self.connect()
        return self._min_range_m

    def connect(self) -> None:
        if self._depth is not None:
            return
        counts = recorded_frames(self.path)
        try:
            self._depth = _StreamPlayer(self.path, rs.stream.depth, counts)
            self._color = _StreamPlayer(self.path, rs.stream.color, counts)
            self._setup()
        except RuntimeError as exc:
            self.disconnect()
            raise RecordingError(
                f"cannot play RealSense recording {self.path}: {exc}; the file is truncated, corrupt or lacks a "
                "colour and a depth stream: record it again with both streams (the RealSense Viewer's record button, "
                "or `rs-record`), or record a frames directory instead (`deploy record --camera d415 --out DIR`)"
            ) from None
        except BaseException:  # whatever it is (Ctrl-C too), no player is left started
            self.disconnect()
            raise
        # players still started when the camera is dropped unclosed would hang the process at exit
        self._finalizer = weakref.finalize(self, _close_players, self._depth, self._color)
        self.recorded = {"depth": self._depth.expected, "color": self._color.expected}
        self.delivered = {"depth": 0, "color": 0}
        self.unpaired = {"depth": 0, "color": 0}
        self.frames_read = 0

    def _setup(self) -> None:
        depth, color = self._depth, self._color
        self._depth_scale = float(depth.sensor.as_depth_sensor().get_depth_scale())
        product = depth.device.get_info(rs.camera_info.name) if depth.device.supports(rs.camera_info.name) else None
        model = model_of(product)
        self._min_range_m = None if model is None else model.min_range_m(depth.profile.height())
        self._color_format = color.profile.format()
        if self._color_format not in _COLOR_FORMATS:
            raise RuntimeError(f"colour format {self._color_format} is not RGB8/BGR8/RGBA8/BGRA8")
        self._intrinsics = intrinsics_of(color.profile)
        # the depth -> colour extrinsics, within the depth stream's device (where the colour stream is not played)
        color_there = next((p for s in depth.device.query_sensors() for p in s.get_stream_profiles()
                            if p.stream_type() == rs.stream.color and p.format() == self._color_format
                            and p.stream_index() == color.profile.stream_index()), None)
        if color_there is None:
            raise RuntimeError("no colour stream beside the depth stream")
        self._extrinsics = depth.profile.get_extrinsics_to(color_there)
        if color.profile.fps() <= 0:
            raise RuntimeError(f"its colour stream has no frame rate ({color.profile.fps()} fps)")
        self._period_ms = 1000.0 / color.profile.fps()
        self._filters = build_filters(self.filters)
        self._aligners: dict[Intrinsics, DepthAligner] = {}
        self._t0_ms: float | None = None
        self._n0 = 0

    def disconnect(self) -> None:
        _close_players(self._depth, self._color)
        if self._depth is not None and self._color is not None:
            self.delivered = {"depth": self._depth.delivered, "color": self._color.delivered}
        self._depth = self._color = None

    def read(self, timeout_s: float = 2.0) -> Frame:
        """The next recorded colour + depth pair; RecordingError at the end of the file. Not in real time: waits
        as long as the playback plays (`timeout_s` is not used); CameraError if librealsense stalls."""
        self.connect()
        pair = self._next_pair()
        if pair is None:
            raise RecordingError(f"end of RealSense recording {self.path} after {self.frames_read} frames")
        self.frames_read += 1
        return self._to_frame(*pair)

    def _next_pair(self) -> tuple[rs.frame, rs.frame] | None:
        depth, color, half = self._depth, self._color, self._period_ms / 2
        try:
            while True:
                d, c = depth.peek(), color.peek()
                if d is None or c is None:
                    self._count_rest()
                    return None
                td, tc = d.get_timestamp(), c.get_timestamp()
                if td < tc - half or self._closer(depth, tc, td):
                    depth.take()
                    self.unpaired["depth"] += 1
                elif tc < td - half or self._closer(color, td, tc):
                    color.take()
                    self.unpaired["color"] += 1
                else:
                    return depth.take(), color.take()
        finally:
            self.delivered = {"depth": depth.delivered, "color": color.delivered}

    @staticmethod
    def _closer(player: _StreamPlayer, t_other: float, t: float) -> bool:
        """Whether the frame after `player`'s next one (at `t`) lies closer to `t_other` than that one."""
        after = player.peek(1)
        return after is not None and abs(after.get_timestamp() - t_other) < abs(t - t_other)

    def _count_rest(self) -> None:
        """At the end of one stream, the other's remaining frames have no partner: count them."""
        for key, player in (("depth", self._depth), ("color", self._color)):
            while player.take() is not None:
                self.unpaired[key] += 1

    def lost_frames(self) -> str | None:
        """What librealsense failed to play of the recording (after reading it to its end), or None when it played
        every frame the recording's index lists (or the index could not be read)."""
        short = [f"{self.delivered[k]} of {self.recorded[k]} {name} frames" for k, name in
                 (("depth", "depth"), ("color", "colour"))
                 if self.recorded is not None and self.recorded[k] is not None
                 and self.delivered[k] < self.recorded[k]]
        return None if not short else "librealsense played only " + " and ".join(short)

    def _to_frame(self, depth: rs.frame, color: rs.frame) -> Frame:
        stamp_ms, number = depth.get_timestamp(), depth.get_frame_number()
        if self._t0_ms is None:
            self._t0_ms, self._n0 = stamp_ms, number
        for f in self._filters:
            depth = f.process(depth)
        return Frame(index=number - self._n0, t=(stamp_ms - self._t0_ms) / 1000.0,
                     color=to_rgb(color, self._color_format), depth_m=self._aligned_depth(depth),
                     intrinsics=self._intrinsics)

    def _aligned_depth(self, depth: rs.frame) -> np.ndarray:
        """The depth frame on the colour image's pixel grid, in metres, by `DepthAligner` (no rounding holes;
        co-registered streams pass through unchanged; the colour lens's distortion applied)."""
        intrinsics = intrinsics_of(depth.get_profile().as_video_stream_profile())
        aligner = self._aligners.get(intrinsics)
        if aligner is None:
            e = self._extrinsics
            aligner = self._aligners[intrinsics] = DepthAligner(
                intrinsics, self._intrinsics, np.reshape(e.rotation, (3, 3)).T, e.translation)
        units = np.asanyarray(depth.get_data())
        return aligner.align(units.astype(np.float32) * np.float32(self._depth_scale))


def _close_players(*players: _StreamPlayer | None) -> None:
    for player in players:
        if player is not None:
            player.close()

