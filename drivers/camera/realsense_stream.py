"""The librealsense pipeline shared by the live D415 and .bag/.db3 playback: start, depth scale,
post-processing, alignment of depth to colour, and framesets as `Frame`s.

Recordings (playback, not real time) pair colour and depth frames by timestamp and align depth to colour
with `DepthAligner`: no rounding holes, co-registered streams pass through unchanged, lens distortion is
ignored (the D415 reports none worth correcting). The live camera uses librealsense's `rs.align` (C++, keeps
up with 30 fps; it leaves some one-pixel rounding holes)."""

from __future__ import annotations

from collections import deque

import cv2
import numpy as np
import pyrealsense2 as rs

from drivers.camera.base import Frame, Intrinsics
from drivers.camera.depth_align import DepthAligner
from drivers.camera.realsense_config import HOLE_FILLING, FilterConfig

PENDING = 32  # playback frames kept per stream while waiting for their partner
_TO_RGB = {
    rs.format.rgb8: None, rs.format.bgr8: cv2.COLOR_BGR2RGB,
    rs.format.rgba8: cv2.COLOR_RGBA2RGB, rs.format.bgra8: cv2.COLOR_BGRA2RGB,
}


def build_filters(config: FilterConfig) -> list[rs.filter]:
    """The post-processing chain of `config`, in librealsense's recommended order."""
    chain: list[rs.filter] = []
    if config.decimation > 1:
        decimation = rs.decimation_filter()
        decimation.set_option(rs.option.filter_magnitude, config.decimation)
        chain.append(decimation)
    if config.spatial or config.temporal:
        chain.append(rs.disparity_transform(True))
        if config.spatial:
            spatial = rs.spatial_filter()
            spatial.set_option(rs.option.filter_smooth_alpha, config.spatial_alpha)
            spatial.set_option(rs.option.filter_smooth_delta, config.spatial_delta)
            chain.append(spatial)
        if config.temporal:
            temporal = rs.temporal_filter()
            temporal.set_option(rs.option.filter_smooth_alpha, config.temporal_alpha)
            temporal.set_option(rs.option.filter_smooth_delta, config.temporal_delta)
            chain.append(temporal)
        chain.append(rs.disparity_transform(False))
    if config.hole_filling is not None:
        chain.append(rs.hole_filling_filter(HOLE_FILLING[config.hole_filling]))
    return chain


def intrinsics_of(profile: rs.video_stream_profile) -> Intrinsics:
    """Our pinhole intrinsics from a librealsense video stream profile."""
    i = profile.get_intrinsics()
    return Intrinsics(i.width, i.height, float(i.fx), float(i.fy), float(i.ppx), float(i.ppy))


class RealSenseStream:
    """A started pipeline delivering aligned colour + metric depth.

    `config` selects the device or file (`rs.config`). Playback is switched to not-real-time, so
    every recorded frame is delivered once, in order, however slow the reader. Raises RuntimeError
    from librealsense when the pipeline cannot start; callers turn it into CameraError/RecordingError.
    """

    def __init__(self, config: rs.config, filters: FilterConfig) -> None:
        self.pipeline = rs.pipeline()
        resolved = config.resolve(rs.pipeline_wrapper(self.pipeline)).get_device()
        if resolved.is_playback():  # before start, or the first frames may be dropped
            resolved.as_playback().set_real_time(False)
        self.profile = self.pipeline.start(config)
        try:
            self.device = self.profile.get_device()
            self.playback = self.device.as_playback() if self.device.is_playback() else None
            self.depth_scale = float(self.device.first_depth_sensor().get_depth_scale())
            color = self.profile.get_stream(rs.stream.color).as_video_stream_profile()
            self.fps = color.fps()
            self.intrinsics = intrinsics_of(color)
            self.color_format = color.format()
            if self.color_format not in _TO_RGB:
                raise RuntimeError(f"colour format {self.color_format} is not RGB8/BGR8/RGBA8/BGRA8")
        except Exception:
            self.pipeline.stop()
            raise
        self._color_profile = color
        self._align = rs.align(rs.stream.color)
        self._aligners: dict[Intrinsics, DepthAligner] = {}
        self._filters = build_filters(filters)
        self._t0_ms: float | None = None
        self._n0: int | None = None
        self._pending: dict[str, deque[rs.frame]] = {"depth": deque(maxlen=PENDING), "color": deque(maxlen=PENDING)}
        self._last_number: dict[str, int] = {}
        self.timed_out = False  # whether the last poll got no frameset at all

    def poll(self, timeout_s: float) -> Frame | None:
        """The next aligned frame, or None if none arrived within `timeout_s` (then `timed_out`). In playback the
        colour and depth frames are paired by timestamp (within half a frame period) whichever framesets the
        syncer, not in real time, groups them in; repeated frames are skipped."""
        if self.playback is not None and (pair := self._pair()) is not None:
            self.timed_out = False
            return self._playback_frame(*pair)
        ok, frames = self.pipeline.try_wait_for_frames(max(1, int(timeout_s * 1000)))
        self.timed_out = not ok
        if not ok:
            return None
        if self.playback is not None:
            self._queue(frames)
            pair = self._pair()
            return None if pair is None else self._playback_frame(*pair)
        if not frames.get_depth_frame() or not frames.get_color_frame():
            return None
        return self._live_frame(frames)

    def _queue(self, frames: rs.composite_frame) -> None:
        """Keep the frameset's new depth and colour frames for pairing."""
        for kind, frame in (("depth", frames.get_depth_frame()), ("color", frames.get_color_frame())):
            if frame and frame.get_frame_number() != self._last_number.get(kind):
                self._last_number[kind] = frame.get_frame_number()
                frame.keep()
                self._pending[kind].append(frame)

    def _pair(self) -> tuple[rs.frame, rs.frame] | None:
        """The oldest queued depth and colour frames within half a frame period of each other (older unpaired
        frames are dropped), or None."""
        depths, colors = self._pending["depth"], self._pending["color"]
        while depths and colors:
            apart_ms = depths[0].get_timestamp() - colors[0].get_timestamp()
            if abs(apart_ms) <= 500.0 / self.fps:
                return depths.popleft(), colors.popleft()
            (depths if apart_ms < 0 else colors).popleft()
        return None

    def _stamp(self, depth: rs.frame) -> tuple[int, float]:
        """The frame's index and time (s) since the first frame."""
        stamp_ms, number = depth.get_timestamp(), depth.get_frame_number()
        if self._t0_ms is None:
            self._t0_ms, self._n0 = stamp_ms, number
        return number - self._n0, (stamp_ms - self._t0_ms) / 1000.0

    def _rgb(self, color: rs.frame) -> np.ndarray:
        rgb = np.asanyarray(color.get_data())
        conversion = _TO_RGB[self.color_format]
        return rgb.copy() if conversion is None else cv2.cvtColor(rgb, conversion)

    def _live_frame(self, frames: rs.composite_frame) -> Frame:
        """A live frameset: filtered, depth aligned by librealsense."""
        index, t = self._stamp(frames.get_depth_frame())
        for f in self._filters:
            frames = f.process(frames).as_frameset()
        frames = self._align.process(frames)
        depth_m = np.asanyarray(frames.get_depth_frame().get_data()).astype(np.float32) * np.float32(self.depth_scale)
        return Frame(index=index, t=t, color=self._rgb(frames.get_color_frame()), depth_m=depth_m,
                     intrinsics=self.intrinsics)

    def _playback_frame(self, depth: rs.frame, color: rs.frame) -> Frame:
        """A recorded pair: depth filtered, then re-projected onto the colour image by `DepthAligner`."""
        index, t = self._stamp(depth)
        for f in self._filters:
            depth = f.process(depth)
        profile = depth.get_profile().as_video_stream_profile()
        intrinsics = intrinsics_of(profile)
        aligner = self._aligners.get(intrinsics)
        if aligner is None:
            extrinsics = profile.get_extrinsics_to(self._color_profile)
            aligner = self._aligners[intrinsics] = DepthAligner(
                intrinsics, self.intrinsics, np.reshape(extrinsics.rotation, (3, 3)).T, extrinsics.translation)
        depth_m = np.asanyarray(depth.get_data()).astype(np.float32) * np.float32(self.depth_scale)
        return Frame(index=index, t=t, color=self._rgb(color), depth_m=aligner.align(depth_m),
                     intrinsics=self.intrinsics)

    def stop(self) -> None:
        """Stop the pipeline (idempotent; errors of a vanished device are ignored). Playback is paused first:
        stopping a not-real-time playback at its end aborted librealsense 2.59 about once in 100-200 replays
        (heap corruption in `pipeline.stop`); paused, 1200 replays in a row stopped cleanly."""
        try:
            if self.playback is not None:
                self.playback.pause()
            self.pipeline.stop()
        except RuntimeError:
            pass

