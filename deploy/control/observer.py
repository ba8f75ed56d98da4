"""The episode's eyes: frames grabbed during motions (every 1/camera_hz of arm time), then, between motions,
segmented and fed to the axis pipeline (the gripper's pose with them only where it held the handle); the first
frame fixes the body box. The self-filter removes the arm's own pixels (depth and mask) before anything else sees
a frame; the run folder keeps what the camera saw, marking whether the gripper held the handle.

With a pointer (the user's `--point` / `--box`, in simulation the simulated user's pixel) the first frame's pointed
part (deploy/perception/pointing.py) gives the object: the furniture's and the front's pixels are the static
reference, later masks come from the static scene (`StaticSceneTracker`) and the moving part is what leaves it in
front of the pointed front (its opening region). A segmenter that reads the simulator's labels (the oracle ablation)
keeps its own masks.

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
from deploy.errors import PointerError
from deploy.geometry.estimators.base import Observation
from deploy.geometry.static_scene import tolerance_m
from deploy.geometry.types import AxisResult, Box, JointType, NoAxis
from deploy.perception.base import Pointer, Segmenter
from deploy.perception.handle import GripperSize
from deploy.perception.pointing import PointedPart, point_at
from deploy.perception.registry import needs
from deploy.perception.self_filter import SelfFilter
from deploy.perception.static_tracker import StaticSceneTracker, front_region
from deploy.report.run_folder import RunFolder
from drivers.arm.base import ArmState
from drivers.arm.kinematics import Kinematics
from drivers.camera.base import Camera, Frame

log = logging.getLogger(__name__)

NEAR_OBJECT_PX = 9  # the arm's pixels within this square around the object's count as near it
POINTED_PATCH_PX = 5  # the pointed part's depth is read on the pixels this near the pointed pixel (either way)
STILL_RADIUS_M = 0.08  # ... and on the pointed front's pixels this near it (a drawer front is 10 cm tall and more)
STILL_SHARE = 0.8  # the pointed part stands where it was when this share of those pixels read the first frame's depth
NEAR_POINTER_PX = 90  # a pointed part the arm hides: the arm's pixels this near the pointed pixel count (a 30 cm front
# at 1 m is about 180 pixels across)


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
        self._looked: Frame | None = None  # the first frame, the arm's pixels removed
        self._pointed: PointedPart | None = None
        self._tracker: StaticSceneTracker | None = None  # follows the pointed part's furniture
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

    @property
    def pointed(self) -> PointedPart | None:
        """The part the user pointed at on the first frame (None without a pointer, or with a labelling segmenter)."""
        return self._pointed

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
        """How many pixels near the object on the first frame (around the pointed pixel when the pointed part was not
        found) the arm at joints `q` would hide; None without a self-filter to tell."""
        if self._self_filter is None or self._looked is None:
            return None
        robot = self._self_filter.mask(self._looked, q, gripper_width_m, depth_test=False)
        return int(np.count_nonzero(self._near_object & robot))

    def pointed_still(self) -> bool | None:
        """Whether the part the user pointed at still stands where the first frame showed it: on the latest frame,
        STILL_SHARE of the pointed front's pixels within STILL_RADIUS_M of the pointed pixel (the pixels around it when
        the front found does not hold it) that neither frame's arm hides read the first frame's depth (within the
        static scene's tolerance): a drawer pulled out may show its inside at its front's old depth at one place, not
        across its front. None without a pointer, a latest frame, or such pixels."""
        pointer = Pointer.of(self._config.perception.point, self._config.perception.box)
        if pointer is None or self._looked is None or self._last_seen is None:
            return None
        region = _pointed_region(self._looked, self._pointed, pointer.pixel())
        if region is None:
            return still_around(self._looked, self._last_seen[0], pointer.pixel())
        return still_on(self._looked, self._last_seen[0], region)

    def times(self) -> FrameTimes:
        return FrameTimes(self._seconds, list(self._frame_ms), list(self._frame_cpu_ms))

    # --- acting ------------------------------------------------------------------------------------------------

    def set_joint(self, joint: JointType) -> None:
        """The joint the probe pull classified: the pipeline cuts a door's moving part out of a deeper box."""
        self._pipeline.joint = joint

    def first(self, arm_state: Callable[[], ArmState], commanded: Callable[[], np.ndarray | None] | None = None,
              gripper: GripperSize | None = None) -> FirstLook:
        """Read and segment the first frame (the arm's state, and `commanded()` joints, read after it), fix the body
        box; what it showed. With a pointer the pointed part is found first (PointerError: one line on what was seen
        there), `gripper` judging its handle. Called again, it starts over (a new body box)."""
        raw = self._camera.read()
        state = arm_state()
        q_commanded = None if commanded is None else commanded()
        frame, robot = self._without_robot(raw, state)
        self._looked = frame
        try:
            mask = self._start(frame, robot, gripper)
        except PointerError:  # the run folder keeps the frame the user pointed at
            self._log(raw, np.zeros(raw.depth_m.shape, bool), state, self._kin.fk(state.q), first=True,
                      commanded=q_commanded)
            self._near_object = _around(self._config.perception.point, frame.depth_m.shape)
            raise
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
        found = "the pointed part's furniture" if self._pointed is not None else \
            f"segmenter {self._segmenter.name} found the object (prompt {self._config.perception.object_prompt!r})"
        log.info("first frame %d: %s: %d pixels in box %s px, %d points", frame.index, found, self._mask_pixels,
                 _box_text(mask), len(points))
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
            mask = self._track(frame) & ~robot
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

    def look(self, state: ArmState) -> tuple[Frame, np.ndarray, np.ndarray]:
        """A fresh frame (the arm at `state`, its pixels removed), its object cloud (base frame) and the arm's pixels,
        outside any motion (re-grasp)."""
        frame, robot = self._without_robot(self._camera.read(), state)
        return frame, self.points(frame, self._track(frame) & ~robot), robot

    def _start(self, frame: Frame, robot: np.ndarray, gripper: GripperSize | None) -> np.ndarray:
        """The first frame's object mask, and the pipeline (and tracker) that follow it: the pointed part's furniture
        and front, in the static scene, when the user pointed (and the segmenter reads no labels); else the
        segmenter's."""
        perception = self._config.perception
        pointer = Pointer.of(perception.point, perception.box)
        self._pointed = self._tracker = None
        if pointer is None or needs(self._segmenter.name, "labels"):
            self._pipeline = AxisPipeline(self._pipeline_config)
            return self._segmenter.start(frame, perception.object_prompt, Pointer.of(perception.point)) & ~robot
        self._pointed = point_at(frame, robot, pointer, gripper=gripper)
        mask = (self._pointed.furniture.mask | self._pointed.front.mask) & ~robot
        region = front_region(frame, self._pointed.front.mask, perception.opening_reach_m)
        self._tracker = StaticSceneTracker(frame, mask, region)
        self._pipeline = AxisPipeline(self._pipeline_config, region=region)
        log.info("pointed part (%s): a %.2f x %.2f m front with a %s, furniture %d pixels", pointer,
                 self._pointed.front.width_m, self._pointed.front.height_m, self._pointed.handle.kind,
                 int(np.count_nonzero(mask)))
        return mask

    def _track(self, frame: Frame) -> np.ndarray:
        return self._segmenter.track(frame) if self._tracker is None else self._tracker.track(frame)

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


def still_around(first: Frame, later: Frame, pixel: tuple[int, int], half: int = POINTED_PATCH_PX) -> bool | None:
    """Whether the surface around `pixel` (row, column) of `first` is still there on `later` (the same camera): of
    the pixels within `half` of it with depth on both frames (at least half of them), STILL_SHARE read the same
    depth within `tolerance_m`; None when fewer have depth on both (the arm hides them, or the pixel is off the
    image)."""
    r, c = pixel
    h, w = first.depth_m.shape
    if not (0 <= r < h and 0 <= c < w):
        return None
    window = np.zeros((h, w), bool)
    window[max(r - half, 0):r + half + 1, max(c - half, 0):c + half + 1] = True
    return still_on(first, later, window)


def _pointed_region(first: Frame, pointed: PointedPart | None, pixel: tuple[int, int]) -> np.ndarray | None:
    """The pointed front's pixels within STILL_RADIUS_M of `pixel` (row, column) on `first`; None when no front was
    found there (or the pixel has no depth)."""
    r, c = pixel
    h, w = first.depth_m.shape
    if pointed is None or not (0 <= r < h and 0 <= c < w) or not pointed.front.mask[r, c] or first.depth_m[r, c] <= 0:
        return None
    radius = STILL_RADIUS_M * first.intrinsics.fx / float(first.depth_m[r, c])
    v, u = np.ogrid[:h, :w]
    return pointed.front.mask & ((v - r) ** 2 + (u - c) ** 2 <= radius ** 2)


def still_on(first: Frame, later: Frame, region: np.ndarray) -> bool | None:
    """Whether the surface on the pixels `region` (H, W bool) of `first` is still there on `later` (the same
    camera): of those with depth on both frames (at least half of them), STILL_SHARE read the same depth within
    `tolerance_m`; None when fewer have depth on both (the arm hides them) or the region is empty."""
    before, after = first.depth_m[region], later.depth_m[region]
    both = (before > 0) & (after > 0)
    if not before.size or np.count_nonzero(both) < 0.5 * before.size:
        return None
    same = np.abs(after[both] - before[both]) <= tolerance_m(before[both], first.intrinsics.fx)
    return bool(np.mean(same) >= STILL_SHARE)


def _around(point: tuple[float, float] | None, shape: tuple[int, int]) -> np.ndarray:
    """The pixels within NEAR_POINTER_PX of the pointed pixel (none without one)."""
    near = np.zeros(shape, bool)
    if point is not None:
        v, u = np.ogrid[:shape[0], :shape[1]]
        near = (u - point[0]) ** 2 + (v - point[1]) ** 2 <= NEAR_POINTER_PX ** 2
    return near


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
