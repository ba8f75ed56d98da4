"""One geometry step per camera frame: cloud -> radius filter -> body box or moving part -> axis estimate.

The first frame fixes the body box (handle removed); every later frame's moving part joins a sliding
window of observations from which the estimator re-estimates the axis.
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
from deploy.geometry.types import AxisResult, Box, JointType, NoAxis
from drivers.camera.base import Frame


@dataclass(frozen=True)
class StepResult:
    """What one frame produced: the estimate and the sizes and timings behind it."""

    index: int
    t: float
    result: AxisResult
    object_points: int
    moving_points: int
    timings_ms: dict[str, float] = field(default_factory=dict)


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
    """Stateful runner of the per-frame geometry (the functions it calls are pure)."""

    def __init__(self, config: Config, estimator: AxisEstimator | None = None):
        self.config = config
        self.filter = config.filter.resolve()
        self.estimator = estimator or make_estimator(config.estimator.name, config.estimator)
        joint = config.estimator.joint
        self.joint = None if joint == "auto" else JointType(joint)
        self.window: deque[Observation] = deque(maxlen=config.estimator.window)
        self.body_box: Box | None = None
        self.front = np.zeros(3)  # outward normal of the body box's front face (toward the camera)
        self.handle_points = np.empty((0, 3))

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
        """Feed one frame's object cloud; the first call fixes the body box and returns NoAxis.

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
        clock = time.perf_counter()
        moving = moving_part(
            points, self.cut_box(), margin_m=self.config.geometry.body_margin_m,
            radius_m=self.filter.radius_m, eps=self.filter.eps,
        )
        timings["moving_part"] = (time.perf_counter() - clock) * 1e3
        self.window.append(Observation(index, t, moving, self.body_box, gripper_pose))
        clock = time.perf_counter()
        result = self.estimator.estimate(list(self.window), self.joint)
        timings["estimate"] = (time.perf_counter() - clock) * 1e3
        return StepResult(index, t, result, len(points), len(moving), timings)

    def _first(self, kept: np.ndarray, index: int, t: float, view: np.ndarray, timings: dict) -> StepResult:
        if len(kept) < 4:
            return StepResult(index, t, NoAxis("no object points on the first frame: check the mask"),
                              len(kept), 0, timings)
        clock = time.perf_counter()
        if self.config.geometry.remove_handle:
            self.body_box, _, self.handle_points = remove_handle(kept, view, box_fn=lambda p: self._box(p, view))
        else:
            self.body_box = self._box(kept, view)
        self.front = front_direction(self.body_box, view)
        timings["body_box"] = (time.perf_counter() - clock) * 1e3
        return StepResult(index, t, NoAxis("first frame: body box fixed, waiting for motion"), len(kept), 0,
                          timings)

    def update_frame(self, frame: Frame, mask: np.ndarray, gripper_pose: np.ndarray | None = None) -> StepResult:
        """`update` on a camera frame and its object mask."""
        clock = time.perf_counter()
        points = frame_points(frame, mask, self.config)
        cloud_ms = (time.perf_counter() - clock) * 1e3
        step = self.update(points, frame.index, frame.t, viewpoint(frame), gripper_pose)
        step.timings_ms["cloud"] = cloud_ms
        return step
