"""One geometry step per camera frame: cloud -> radius filter -> body box or moving part -> axis estimate.

The first frame fixes the body box (handle removed) and, for the static-scene moving part, the static scene and the
opening region; every later frame's moving part joins a sliding window of observations from which the estimator
re-estimates the axis. The moving part is what left the first frame's static surfaces within the opening region
(`[geometry] moving_part` "static-scene", deploy/geometry/static_scene.py), or what left its body box (the paper's,
"box"); "auto" gives the estimator its own (paper-obb: the box).
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from deploy.config import Config
from deploy.geometry.boxes import extend_behind, front_box, front_direction, oriented_box, remove_handle, yaw_box
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.estimators.registry import make_estimator
from deploy.geometry.moving_part import moving_part
from deploy.geometry.radius_filter import radius_filter
from deploy.geometry.static_scene import StaticScene, moving_pixels, opening_reach_m, opening_region, static_scene
from deploy.geometry.types import AxisResult, Box, JointType, NoAxis
from drivers.camera.base import Frame

PAUSE_M = 0.002  # the gripper moved less than this since the last frame in the window: a pause (twice the 1 mm its
# position from forward kinematics is good to, `[estimator.screw] grip_noise_m`)


@dataclass(frozen=True)
class StepResult:
    """What one frame produced: the estimate and the sizes and timings behind it."""

    index: int
    t: float
    result: AxisResult
    object_points: int
    moving_points: int
    timings_ms: dict[str, float] = field(default_factory=dict)
    moving: np.ndarray | None = None  # the moving part's points (None on the first frame)


def frame_points(frame: Frame, mask: np.ndarray, config: Config) -> np.ndarray:
    """The masked depth of `frame` as an (N,3) cloud in the base frame (camera frame without a pose).

    With `geometry.decimation` n > 1 only every n-th pixel in each direction is used (like the
    RealSense decimation filter, without averaging): n^2 times fewer points for the same surfaces.
    """
    g = config.geometry
    n = g.decimation
    K = np.diag([1.0 / n, 1.0 / n, 1.0]) @ frame.intrinsics.K
    return depth_to_points(
        frame.depth_m[::n, ::n], K, mask=np.asarray(mask)[::n, ::n], T_base_camera=frame.T_base_camera,
        min_depth_m=g.near_m, max_depth_m=g.max_depth_m, dist=frame.intrinsics.dist_coeffs,
    )


def viewpoint(frame: Frame) -> np.ndarray:
    """The camera centre in the frame the points are expressed in."""
    return np.zeros(3) if frame.T_base_camera is None else np.asarray(frame.T_base_camera)[:3, 3]


class AxisPipeline:
    """Stateful runner of the per-frame geometry (the functions it calls are pure).

    `region`: where the target part can be while it opens (`static_scene.opening_region` of its front), for the
    static-scene moving part; None: the first frame's body box's front face, reaching `perception.opening_reach_m`
    (or the front's width, if larger) out of it. `toward`: a point in front of the target's front (the base of
    the robot that opens it): the body box's front is its face the ray from its centre toward that point leaves
    through; None: toward the camera.
    """

    def __init__(self, config: Config, estimator: AxisEstimator | None = None, region: Box | None = None,
                 toward: np.ndarray | None = None):
        self.config = config
        self.filter = config.filter.resolve()
        self.estimator = estimator or make_estimator(config.estimator.name, config.estimator)
        joint = config.estimator.joint
        self.joint = None if joint == "auto" else JointType(joint)
        self.window: deque[Observation] = deque(maxlen=config.estimator.window)
        self.body_box: Box | None = None
        self.front = np.zeros(3)  # outward normal of the body box's front face (toward the camera)
        self.handle_points = np.empty((0, 3))
        mode = config.geometry.moving_part
        self.static = mode == "static-scene" or (mode == "auto" and not self.estimator.box_moving_part)
        self.region = region
        self.toward = None if toward is None else np.asarray(toward, float)
        self.scene: StaticScene | None = None
        self._joined: np.ndarray | None = None  # the gripper pose of the frame that last joined the window

    def _paused(self, gripper_pose: np.ndarray | None) -> bool:
        """Whether the gripper, at `gripper_pose`, is within PAUSE_M of where it was at the frame that last joined
        the window (False without both poses)."""
        if gripper_pose is None or self._joined is None or not self.window:
            return False
        return bool(np.linalg.norm(np.asarray(gripper_pose)[:3, 3] - self._joined[:3, 3]) < PAUSE_M)

    def cut_box(self) -> Box:
        """The box the moving part is cut out of: the body box, reaching geometry.inside_depth_m behind the
        front for a door (the inside it reveals is static; a drawer's revealed inside is the drawer). It
        follows `joint`, which `--joint auto` sets once the joint is classified."""
        inside = self.config.geometry.inside_depth_m if self.joint is JointType.REVOLUTE else 0.0
        return extend_behind(self.body_box, self.front, inside)

    def _box(self, points: np.ndarray, view: np.ndarray) -> Box:
        kind = self.config.geometry.box
        if kind == "front":
            return front_box(points, view)
        return yaw_box(points) if kind == "yaw" else oriented_box(points)

    def update(
        self, points: np.ndarray, index: int, t: float, view: np.ndarray, gripper_pose: np.ndarray | None = None
    ) -> StepResult:
        """Feed one frame's object cloud; the first call fixes the body box and returns NoAxis; later calls cut the
        moving part out of the body box (the static-scene moving part needs the depth image: `update_frame`).

        The whole cloud is radius-filtered on the first frame only (for the body box). Later frames
        filter just the points outside the box, which is all the moving part needs: the paper filters
        the whole cloud first as well, which can only differ where an outside point's neighbour was
        itself an outlier of the whole cloud, and filters far more points.
        """
        timings: dict[str, float] = {}
        if self.body_box is None:
            clock = time.perf_counter()
            kept = radius_filter(points, self.filter.radius_m, self.filter.eps)
            timings["filter"] = (time.perf_counter() - clock) * 1e3
            return self._first(kept, index, t, view, timings)
        if self.static:
            raise ValueError("AxisPipeline.update: the static-scene moving part compares depth images: feed frames "
                             "with update_frame, or set [geometry] moving_part = \"box\"")
        clock = time.perf_counter()
        moving = moving_part(
            points, self.cut_box(), margin_m=self.config.geometry.body_margin_m,
            radius_m=self.filter.radius_m, eps=self.filter.eps,
        )
        timings["moving_part"] = (time.perf_counter() - clock) * 1e3
        return self._estimate(moving, index, t, len(points), gripper_pose, timings)

    def _estimate(self, moving: np.ndarray, index: int, t: float, object_points: int,
                  gripper_pose: np.ndarray | None, timings: dict) -> StepResult:
        """The moving part joins the window; the estimator's answer on it. A frame in which the held handle has not
        moved by PAUSE_M since the last frame that joined takes the newest frame's place instead (`_paused`): a
        pause repeats a view without adding motion, and would push the motion out of the window."""
        observation = Observation(index, t, moving, self.body_box, gripper_pose)
        if self._paused(gripper_pose):
            self.window[-1] = observation
        else:
            self.window.append(observation)
            self._joined = gripper_pose
        clock = time.perf_counter()
        result = self.estimator.estimate(list(self.window), self.joint)
        timings["estimate"] = (time.perf_counter() - clock) * 1e3
        return StepResult(index, t, result, object_points, len(moving), timings, moving)

    def _first(self, kept: np.ndarray, index: int, t: float, view: np.ndarray, timings: dict) -> StepResult:
        if len(kept) < 4:
            return StepResult(index, t, NoAxis("no object points on the first frame: check the mask"),
                              len(kept), 0, timings)
        clock = time.perf_counter()
        if self.toward is not None:
            view = self.toward
        if self.config.geometry.remove_handle:
            self.body_box, _, self.handle_points = remove_handle(kept, view, box_fn=lambda p: self._box(p, view))
        else:
            self.body_box = self._box(kept, view)
        self.front = front_direction(self.body_box, view)
        timings["body_box"] = (time.perf_counter() - clock) * 1e3
        return StepResult(index, t, NoAxis("first frame: body box fixed, waiting for motion"), len(kept), 0,
                          timings)

    def update_frame(self, frame: Frame, mask: np.ndarray, gripper_pose: np.ndarray | None = None) -> StepResult:
        """`update` on a camera frame and its object mask (the arm's pixels out of it). With the static-scene moving
        part the first frame also fixes the static scene, and on later frames the moving part is what left it within
        the opening region and the mask; PerceptionError when the camera moved since the first frame."""
        clock = time.perf_counter()
        if self.static and self.body_box is not None:
            self.scene.check_view(frame.depth_m, frame.T_base_camera)
            g = self.config.geometry
            _, moving = moving_pixels(self.scene, frame.depth_m, self.region, mask, (g.near_m, g.max_depth_m))
            timings = {"moving_part": (time.perf_counter() - clock) * 1e3}
            object_pixels = int(np.count_nonzero(np.asarray(mask)[::g.decimation, ::g.decimation]))
            return self._estimate(moving, frame.index, frame.t, object_pixels, gripper_pose, timings)
        points = frame_points(frame, mask, self.config)
        cloud_ms = (time.perf_counter() - clock) * 1e3
        step = self.update(points, frame.index, frame.t, viewpoint(frame), gripper_pose)
        step.timings_ms["cloud"] = cloud_ms
        if self.static and self.body_box is not None:
            clock = time.perf_counter()
            self._fix_scene(frame)
            step.timings_ms["static_scene"] = (time.perf_counter() - clock) * 1e3
        return step

    def _fix_scene(self, frame: Frame) -> None:
        """The first frame's static scene, and the opening region when none was given."""
        self.scene = static_scene(frame.depth_m, frame.intrinsics.K, self.config.geometry.decimation,
                                  frame.T_base_camera)
        if self.region is None:
            reach = opening_reach_m(self.body_box, self.front, self.config.perception.opening_reach_m)
            self.region = opening_region(self.body_box, self.front, reach)
