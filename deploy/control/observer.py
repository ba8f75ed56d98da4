"""The episode's eyes: frames grabbed during motions (every 1/camera_hz of arm time), then, between motions,
segmented and fed to the axis pipeline (the gripper's pose with them only where it held the handle); the first
frame fixes the body box. The self-filter removes the arm's own pixels (depth and mask) before anything else sees
a frame; the run folder keeps what the camera saw, marking whether the gripper held the handle."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from deploy.axis_pipeline import AxisPipeline, frame_points
from deploy.config import Config
from deploy.control.run_folder import RunFolder
from deploy.control.state import EpisodeStop, StopReason
from deploy.control.viewer import RerunViewer
from deploy.geometry.types import AxisResult, JointType, NoAxis
from deploy.perception.base import Segmenter
from deploy.perception.self_filter import SelfFilter
from drivers.arm.base import ArmState
from drivers.arm.kinematics import Kinematics
from drivers.camera.base import Camera, Frame

log = logging.getLogger(__name__)


class Observer:
    """Grabs, segments and estimates. `vision` is the pipeline's latest estimate, `last_seen` the latest
    processed frame with its mask, `first_points` the first frame's object cloud (base frame, m)."""

    def __init__(self, camera: Camera, segmenter: Segmenter, kin: Kinematics, config: Config,
                 joint: JointType | None, t0: float = 0.0, folder: RunFolder | None = None,
                 viewer: RerunViewer | None = None, self_filter: SelfFilter | None = None) -> None:
        self.camera, self.segmenter, self.kin, self.config = camera, segmenter, kin, config
        self.folder, self.viewer, self.self_filter = folder, viewer, self_filter
        self._pipeline_config = config.replace(estimator={
            "name": config.acting_estimator, "joint": "auto" if joint is None else joint.value})
        self.pipeline = AxisPipeline(self._pipeline_config)
        self.first_frame: Frame | None = None
        self.first_mask = np.zeros((0, 0), bool)
        self.first_robot = np.zeros((0, 0), bool)  # the arm's own pixels on the first frame
        self.first_points = np.zeros((0, 3))
        self.last_seen: tuple[Frame, np.ndarray] | None = None
        self.mask_pixels = 0
        self.vision: AxisResult = NoAxis("no frames yet")
        self.pending: list[tuple[Frame, ArmState, bool]] = []  # frame, arm state, whether the gripper held
        self.next_frame_t = 0.0
        self.t0 = t0  # arm-clock start of the episode (viewer timeline)
        self.seconds = 0.0  # spent segmenting and estimating
        self.frame_ms: list[float] = []  # per processed frame: self-filter, segmenter and axis pipeline (wall)
        self.frame_cpu_ms: list[float] = []  # the same frames' CPU time on this thread: one core's work

    def first(self, arm_state: Callable[[], ArmState]) -> tuple[Frame, np.ndarray]:
        """Read and segment the first frame (the arm's state read after it), fix the body box; the frame and
        its object mask. Called again, it starts over (a new body box)."""
        raw = self.camera.read()
        state = arm_state()
        frame, robot = self._without_robot(raw, state)
        self.pipeline = AxisPipeline(self._pipeline_config)
        self.first_frame, self.first_robot = frame, robot
        mask = self.segmenter.start(frame, self.config.perception.object_prompt) & ~robot
        self.mask_pixels, self.first_mask = int(np.count_nonzero(mask)), mask
        if self.mask_pixels == 0:
            raise EpisodeStop(StopReason.NO_OBJECT,
                              "the segmenter found no object on the first frame: point the camera at it")
        self.pipeline.update_frame(frame, mask, None)  # before any grasp: the gripper's pose is not the part's
        self._log(raw, mask, state, self.kin.fk(state.q), first=True, grasped=False)
        self.first_points = frame_points(frame, mask, self.pipeline.config)
        log.info("first frame %d: segmenter %s found the object (prompt %r): %d pixels in box %s px, %d points",
                 frame.index, getattr(self.segmenter, "name", "?"), self.config.perception.object_prompt,
                 self.mask_pixels, _box_text(mask), len(self.first_points))
        if self.viewer is not None:
            self.viewer.cloud(self.first_points)
        self.next_frame_t = state.t
        return frame, mask

    def capture(self, state: ArmState, grasped: bool) -> None:
        """During a motion: grab a frame when its slot has come (frames are processed after the motion);
        `grasped`: the gripper holds the handle at `state`."""
        if state.t + 1e-9 >= self.next_frame_t:
            self.pending.append((self.camera.read(), state, grasped))
            self.next_frame_t = state.t + 1.0 / self.config.opening.camera_hz

    def process(self) -> None:
        """Segment the frames grabbed during the last motion and feed them to the pipeline, in order."""
        clock = time.perf_counter()
        pending, self.pending = self.pending, []
        for raw, state, grasped in pending:
            start, cpu = time.perf_counter(), time.thread_time()
            frame, robot = self._without_robot(raw, state)
            mask = self.segmenter.track(frame) & ~robot
            pose = self.kin.fk(state.q)
            self._log(raw, mask, state, pose, grasped=grasped)
            if np.count_nonzero(mask) < self.config.opening.min_mask_fraction * self.mask_pixels:
                raise EpisodeStop(StopReason.TRACKING_LOST, f"the object's mask shrank to {np.count_nonzero(mask)} "
                                  f"pixels of {self.mask_pixels} at frame {frame.index}: the object left the view "
                                  "or is occluded")
            held = pose if grasped else None  # a slipped grip's path is not the part's
            self.vision = self.pipeline.update_frame(frame, mask, held).result
            if log.isEnabledFor(logging.INFO):  # every frame: no text built unless --verbose shows it
                log.info("frame %d (t %.2f s): %s", frame.index, state.t - self.t0, _estimate_text(self.vision))
            self.last_seen = frame, mask
            self.frame_ms.append((time.perf_counter() - start) * 1e3)
            self.frame_cpu_ms.append((time.thread_time() - cpu) * 1e3)
        self.seconds += time.perf_counter() - clock

    def look(self, state: ArmState) -> tuple[Frame, np.ndarray]:
        """A fresh frame (the arm at `state`, its pixels removed) and its object cloud (base frame), outside any
        motion (re-grasp)."""
        frame, robot = self._without_robot(self.camera.read(), state)
        return frame, frame_points(frame, self.segmenter.track(frame) & ~robot, self.pipeline.config)

    def _without_robot(self, frame: Frame, state: ArmState) -> tuple[Frame, np.ndarray]:
        if self.self_filter is None:
            return frame, np.zeros(frame.depth_m.shape, bool)
        return self.self_filter.apply(frame, state.q, state.gripper_width_m)

    def _log(self, frame: Frame, mask: np.ndarray, state: ArmState, pose: np.ndarray, first: bool = False,
             grasped: bool = False) -> None:
        """Record the frame with the gripper's `pose` (marked `first` where the pipeline starts over on it, and
        whether the gripper held the handle) and show it."""
        if self.folder is not None:
            self.folder.write_frame(frame, mask, state.q, pose, first=first, grasped=grasped)
        if self.viewer is not None:
            self.viewer.frame(state.t - self.t0, frame, mask, pose)


def _box_text(mask: np.ndarray) -> str:
    """The mask's bounding box (x0, y0, x1, y1) in pixels, for the log."""
    ys, xs = np.nonzero(mask)
    return "(none)" if len(xs) == 0 else f"({xs.min()}, {ys.min()}, {xs.max() + 1}, {ys.max() + 1})"


def _estimate_text(result: AxisResult) -> str:
    """One estimate for the log: joint type, direction, origin (m), confidence; or why there is none."""
    if isinstance(result, NoAxis):
        return f"no axis yet ({result.reason})"
    d, o = np.round(result.direction, 3).tolist(), np.round(result.origin, 3).tolist()
    return f"{result.joint_type.value} axis, direction {d}, origin {o} m, confidence {result.confidence:.2f}"
