"""The librealsense pipeline of the live RealSense camera (also of a recording played as a camera, as the tests
do): start, depth scale, post-processing, alignment of depth to colour, and framesets as `Frame`s.
`RealSenseReplayCamera` plays recordings without it (see realsense_playback.py) but shares the filters and colour
conversion here.

Recordings (playback, not real time) and a colour lens with distortion align depth to colour with `DepthAligner`: no
rounding holes, co-registered streams pass through unchanged, and the colour lens's distortion is applied (which
librealsense's x86 `rs.align` leaves out). The live camera with undistorted lenses uses `rs.align` (C++, keeps up
with 30 fps; it leaves some one-pixel rounding holes)."""

from __future__ import annotations

import cv2
import numpy as np
import pyrealsense2 as rs

from drivers.camera.base import DISTORTIONS, Frame, Intrinsics
from drivers.camera.depth_align import DepthAligner
from drivers.camera.realsense_config import HOLE_FILLING, FilterConfig

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
    """Our intrinsics, lens model and coefficients included, from a librealsense video stream profile; RuntimeError
    for a fisheye lens model (a T265's), which frames cannot carry."""
    i = profile.get_intrinsics()
    if i.model.name not in DISTORTIONS:
        raise RuntimeError(f"the {profile.stream_name()} stream's lens model {i.model.name} is not supported (only "
                           f"{', '.join(DISTORTIONS)})")
    return Intrinsics(i.width, i.height, float(i.fx), float(i.fy), float(i.ppx), float(i.ppy), i.model.name,
                      tuple(float(c) for c in i.coeffs))


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
            depth = self.profile.get_stream(rs.stream.depth).as_video_stream_profile()
            self.depth_size = depth.width(), depth.height()
            self.color_format = color.format()
            if self.color_format not in _TO_RGB:
                raise RuntimeError(f"colour format {self.color_format} is not RGB8/BGR8/RGBA8/BGRA8")
        except Exception:
            self.pipeline.stop()
            raise
        self._color_profile = color
        self._distorted = is_distorted(color)
        self._align = rs.align(rs.stream.color)
        self._aligners: dict[Intrinsics, DepthAligner] = {}
        self._filters = build_filters(filters)
        self._t0_ms: float | None = None
        self._n0: int | None = None
        self._last_depth_number: int | None = None
        self.timed_out = False  # whether the last poll got no frameset at all

    def poll(self, timeout_s: float) -> rs.composite_frame | None:
        """The next frameset, kept out of librealsense's frame pool for `to_frame`, or None if none arrived within
        `timeout_s` (then `timed_out`). In playback, partial framesets (colour and depth more than half a frame period
        apart, which the syncer emits when not in real time) and repeated depth frames are skipped. The first
        frameset is the origin of the frames' index and time."""
        ok, frames = self.pipeline.try_wait_for_frames(max(1, int(timeout_s * 1000)))
        self.timed_out = not ok
        if not ok:
            return None
        depth, color = frames.get_depth_frame(), frames.get_color_frame()
        if not depth or not color:
            return None
        if self.playback is not None:
            number = depth.get_frame_number()
            apart_ms = abs(depth.get_timestamp() - color.get_timestamp())
            if number == self._last_depth_number or apart_ms > 500.0 / self.fps:
                return None
            self._last_depth_number = number
        if self._t0_ms is None:
            self._t0_ms, self._n0 = depth.get_timestamp(), depth.get_frame_number()
        frames.keep()
        return frames

    def to_frame(self, frames: rs.composite_frame) -> Frame:
        """A frameset of `poll` as a `Frame`: post-processed, depth aligned to colour, colour as RGB."""
        depth = frames.get_depth_frame()
        stamp_ms, number = depth.get_timestamp(), depth.get_frame_number()
        for f in self._filters:
            frames = f.process(frames).as_frameset()
        rgb = to_rgb(frames.get_color_frame(), self.color_format)
        return Frame(index=number - self._n0, t=(stamp_ms - self._t0_ms) / 1000.0, color=rgb,
                     depth_m=self._aligned_depth(frames), intrinsics=self.intrinsics)

    def _aligned_depth(self, frames: rs.composite_frame) -> np.ndarray:
        """The frameset's depth on the colour image's pixel grid, in metres."""
        depth = frames.get_depth_frame()
        profile = depth.get_profile().as_video_stream_profile()
        if self.playback is None and not (self._distorted or is_distorted(profile)):
            aligned = self._align.process(frames).get_depth_frame()
            return np.asanyarray(aligned.get_data()).astype(np.float32) * np.float32(self.depth_scale)
        intrinsics = intrinsics_of(profile)
        aligner = self._aligners.get(intrinsics)
        if aligner is None:
            extrinsics = profile.get_extrinsics_to(self._color_profile)
            aligner = self._aligners[intrinsics] = DepthAligner(
                intrinsics, self.intrinsics, np.reshape(extrinsics.rotation, (3, 3)).T, extrinsics.translation)
        units = np.asanyarray(depth.get_data())
        return aligner.align(units.astype(np.float32) * np.float32(self.depth_scale))

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


def to_rgb(color: rs.frame, color_format: rs.format) -> np.ndarray:
    """A copy of a colour frame's pixels as (H, W, 3) uint8 RGB (`color_format`: RGB8, BGR8, RGBA8 or BGRA8)."""
    pixels = np.asanyarray(color.get_data())
    conversion = _TO_RGB[color_format]
    return pixels.copy() if conversion is None else cv2.cvtColor(pixels, conversion)


def is_distorted(profile: rs.video_stream_profile) -> bool:
    """Whether a stream's lens model has non-zero distortion coefficients."""
    intrinsics = profile.get_intrinsics()
    return intrinsics.model != rs.distortion.none and any(abs(c) > 0 for c in intrinsics.coeffs)
