"""The episode's eyes: frames grabbed during motions (every 1/camera_hz of arm time), then, between motions,
segmented and fed to the axis pipeline (the gripper's pose with them only where it held the handle); the first
frame fixes the body box. The self-filter removes the arm's own pixels (depth and mask) before anything else sees
a frame; the run folder keeps what the camera saw, marking whether the gripper held the handle.

The observer owns the camera, the segmenter and the axis pipeline; the stages ask it questions (what the first
frame showed, the latest axis, the latest view, the window, how the arm hides the object, its timings) and never
read or write its fields."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from deploy.axis_pipeline import AxisPipeline, frame_points
from deploy.config import Config
from deploy.control.state import EpisodeStop, StopReason
from deploy.control.view import EpisodeView
from deploy.geometry.estimators.base import Observation
from deploy.geometry.types import AxisResult, Box, JointType, NoAxis
from deploy.perception.base import Pointer, Segmenter
from deploy.perception.self_filter import SelfFilter
from deploy.report.run_folder import RunFolder
from drivers.arm.base import ArmState
from drivers.arm.kinematics import Kinematics
from drivers.camera.base import Camera, Frame

log = logging.getLogger(__name__)

NEAR_OBJECT_PX = 9  # the arm's pixels within this square around the object's count as near it


@dataclass(frozen=True)
class FirstLook:
    """What the first frame showed: the frame (the arm's pixels removed), the object's mask, the arm's own pixels,
    the object's cloud (base frame, m), its body box (None with too few points) and the points protruding from
    the box's front (where the handle is when the segmenter does not tell it apart)."""

    frame: Frame
    mask: np.ndarray
    robot: np.ndarray
    points: np.ndarray
    body_box: Box | None
    protruding: np.ndarray


@dataclass(frozen=True)
class FrameTimes:
    """Seconds spent segmenting and estimating, and per processed frame its wall and CPU milliseconds (self-filter,
    segmenter and axis pipeline)."""

    seconds: float
    frame_ms: list[float]
    frame_cpu_ms: list[float]


class Observer:
    """Grabs, segments and estimates; answers what the camera has seen."""

    def __init__(self, camera: Camera, segmenter: Segmenter, kin: Kinematics, config: Config,
                 joint: JointType | None, t0: float = 0.0, folder: RunFolder | None = None,
                 view: EpisodeView | None = None, self_filter: SelfFilter | None = None) -> None:
        self._camera, self._segmenter, self._kin, self._config = camera, segmenter, kin, config
        self._folder, self._view, self._self_filter = folder, view or EpisodeView(), self_filter
        self._pipeline_config = config.replace(estimator={
            "name": config.acting_estimator, "joint": "auto" if joint is None else joint.value,
        }).for_range(camera.min_range_m)
        self._pipeline = AxisPipeline(self._pipeline_config)
        self._first: FirstLook | None = None
        self._near_object = np.zeros((0, 0), bool)  # the first frame's object mask, dilated
        self._last_seen: tuple[Frame, np.ndarray] | None = None
        self._mask_pixels = 0
        self._vision: AxisResult = NoAxis("no frames yet")
        self._pending: list[tuple[Frame, ArmState, bool, np.ndarray | None]] = []  # frame, arm state, whether the
        # gripper held, the joints commanded
        self._next_frame_t = 0.0
        self._t0 = t0  # arm-clock start of the episode (viewer timeline)
        self._seconds = 0.0  # spent segmenting and estimating
        self._frame_ms: list[float] = []  # per processed frame: self-filter, segmenter and axis pipeline (wall)
        self._frame_cpu_ms: list[float] = []  # the same frames' CPU time on this thread: one core's work

    # --- questions ---------------------------------------------------------------------------------------------

    @property
    def first_look(self) -> FirstLook | None:
        """What the first frame showed (None before `first`)."""
        return self._first

    def latest_axis(self) -> AxisResult:
        """The axis pipeline's latest estimate (NoAxis with the reason before there is one)."""
        return self._vision

    def latest_view(self) -> tuple[Frame, np.ndarray] | None:
        """The latest processed frame and its object mask (None before any motion's frames)."""
        return self._last_seen

    def window(self) -> tuple[Observation, ...]:
        """The observations the estimator's window holds, oldest first."""
        return tuple(self._pipeline.window)

    def points(self, frame: Frame, mask: np.ndarray) -> np.ndarray:
        """The cloud (base frame, m) of `mask`'s pixels of `frame`, as the pipeline makes it."""
        return frame_points(frame, mask, self._pipeline.config)

    def handle_points(self) -> np.ndarray:
        """The first frame's handle points: the segmenter's handle mask where it tells one apart, else the points
        protruding from the body box's front."""
        look = self._require_first()
        handle_mask = self._segmenter.handle_mask(look.frame)
        return look.protruding if handle_mask is None else self.points(look.frame, handle_mask)

    def arm_near_object(self) -> int:
        """How many of the arm's own pixels on the first frame touch the object's (it may hide part of it)."""
        return int(np.count_nonzero(self._near_object & self._require_first().robot))

    def arm_hiding(self, q: np.ndarray, gripper_width_m: float) -> int | None:
        """How many pixels near the object on the first frame the arm at joints `q` would hide; None without a
        self-filter to tell."""
        if self._self_filter is None or self._first is None:
            return None
        robot = self._self_filter.mask(self._first.frame, q, gripper_width_m, depth_test=False)
        return int(np.count_nonzero(self._near_object & robot))

    def times(self) -> FrameTimes:
        return FrameTimes(self._seconds, list(self._frame_ms), list(self._frame_cpu_ms))

    # --- acting ------------------------------------------------------------------------------------------------

    def set_joint(self, joint: JointType) -> None:
        """The joint the probe pull classified: the pipeline cuts a door's moving part out of a deeper box."""
        self._pipeline.joint = joint

    def first(self, arm_state: Callable[[], ArmState], commanded: Callable[[], np.ndarray | None] | None = None
              ) -> FirstLook:
        """Read and segment the first frame (the arm's state, and `commanded()` joints, read after it), fix the body
        box; what it showed. Called again, it starts over (a new body box)."""
        raw = self._camera.read()
        state = arm_state()
        q_commanded = None if commanded is None else commanded()
        frame, robot = self._without_robot(raw, state)
        self._pipeline = AxisPipeline(self._pipeline_config)
        perception = self._config.perception
        mask = self._segmenter.start(frame, perception.object_prompt, Pointer.of(perception.point)) & ~robot
        self._mask_pixels = int(np.count_nonzero(mask))
        if self._mask_pixels == 0:
            raise EpisodeStop(StopReason.NO_OBJECT,
                              "the segmenter found no object on the first frame: point the camera at it")
        self._pipeline.update_frame(frame, mask, None)  # before any grasp: the gripper's pose is not the part's
        self._log(raw, mask, state, self._kin.fk(state.q), first=True, grasped=False, commanded=q_commanded)
        points = self.points(frame, mask)
        self._first = FirstLook(frame, mask, robot, points, self._pipeline.body_box, self._pipeline.handle_points)
        kernel = np.ones((NEAR_OBJECT_PX, NEAR_OBJECT_PX), np.uint8)
        self._near_object = cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)
        log.info("first frame %d: segmenter %s found the object (prompt %r): %d pixels in box %s px, %d points",
                 frame.index, self._segmenter.name, self._config.perception.object_prompt,
                 self._mask_pixels, _box_text(mask), len(points))
        self._view.cloud(points)
        self._next_frame_t = state.t
        return self._first

    def capture(self, state: ArmState, grasped: bool, commanded: Callable[[], np.ndarray | None] | None = None) -> None:
        """During a motion: grab a frame when its slot has come (frames are processed after the motion);
        `grasped`: the gripper holds the handle at `state`; `commanded()`: the joints commanded then."""
        if state.t + 1e-9 >= self._next_frame_t:
            q_commanded = None if commanded is None else commanded()
            self._pending.append((self._camera.read(), state, grasped, q_commanded))
            self._next_frame_t = state.t + 1.0 / self._config.opening.camera_hz

    def settled(self, state: ArmState, grasped: bool, commanded: Callable[[], np.ndarray | None] | None = None
                ) -> None:
        """A motion's settled end: a frame now, whatever the slot (the next motion's frames count from it)."""
        self._next_frame_t = 0.0
        self.capture(state, grasped, commanded)

    def process(self) -> None:
        """Segment the frames grabbed during the last motion and feed them to the pipeline, in order."""
        clock = time.perf_counter()
        pending, self._pending = self._pending, []
        for raw, state, grasped, commanded in pending:
            start, cpu = time.perf_counter(), time.thread_time()
            frame, robot = self._without_robot(raw, state)
            mask = self._segmenter.track(frame) & ~robot
            pose = self._kin.fk(state.q)
            self._log(raw, mask, state, pose, grasped=grasped, commanded=commanded)
            if np.count_nonzero(mask) < self._config.opening.min_mask_fraction * self._mask_pixels:
                raise EpisodeStop(StopReason.TRACKING_LOST, f"the object's mask shrank to {np.count_nonzero(mask)} "
                                  f"pixels of {self._mask_pixels} at frame {frame.index}: the object left the view "
                                  "or is occluded")
            held = pose if grasped else None  # a slipped grip's path is not the part's
            self._vision = self._pipeline.update_frame(frame, mask, held).result
            if log.isEnabledFor(logging.INFO):  # every frame: no text built unless --verbose shows it
                log.info("frame %d (t %.2f s): %s", frame.index, state.t - self._t0, _estimate_text(self._vision))
            self._last_seen = frame, mask
            self._frame_ms.append((time.perf_counter() - start) * 1e3)
            self._frame_cpu_ms.append((time.thread_time() - cpu) * 1e3)
        self._seconds += time.perf_counter() - clock

    def look(self, state: ArmState) -> tuple[Frame, np.ndarray]:
        """A fresh frame (the arm at `state`, its pixels removed) and its object cloud (base frame), outside any
        motion (re-grasp)."""
        frame, robot = self._without_robot(self._camera.read(), state)
        return frame, self.points(frame, self._segmenter.track(frame) & ~robot)

    def _require_first(self) -> FirstLook:
        if self._first is None:
            raise RuntimeError("the observer has not looked at the first frame yet: call first() before asking")
        return self._first

    def _without_robot(self, frame: Frame, state: ArmState) -> tuple[Frame, np.ndarray]:
        if self._self_filter is None:
            return frame, np.zeros(frame.depth_m.shape, bool)
        return self._self_filter.apply(frame, state.q, state.gripper_width_m)

    def _log(self, frame: Frame, mask: np.ndarray, state: ArmState, pose: np.ndarray, first: bool = False,
             grasped: bool = False, commanded: np.ndarray | None = None) -> None:
        """Record the frame with the arm's state, the joints `commanded` and the gripper's `pose` (marked `first`
        where the pipeline starts over on it, and whether the gripper held the handle) and show it."""
        if self._folder is not None:
            self._folder.write_frame(frame, mask, state, pose, first=first, grasped=grasped, commanded=commanded)
        self._view.frame(state.t - self._t0, frame, mask, pose)
        self._view.arm(state.t - self._t0, state, commanded)


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
