"""The paper's estimator: yaw-only boxes of the moving part at the two ends of a window.

Rules, as in the paper's released code (without its use of the simulator's true joint value):
- Window: walking back from the newest observation, a prismatic window grows while the moving part has
  >= 1000 points (at most 10 frames), a revolute one while the moving part's box has a side ratio
  (longest / shortest horizontal side) >= 1.2 (at most 8 frames). Every frame in it must also have
  `min_points` points. Only the first (start) and last (end) frames are used.
- Enough motion, from what the robot senses: the end frame's moving part has >= `min_points` points and
  the box centre moved >= `min_travel_m` horizontally from start to end; else NoAxis.
- Prismatic: direction = centre(end) - centre(start) with z zeroed; origin = centre(start).
- Revolute: each box's midline is the line through its centre along its longest horizontal side; the
  pivot is where the two midlines cross in top view (z of the start centre). The direction is +z when
  dot((pivot - c_start) x z, c_end - c_start) > 0, else -z: (pivot - c) x z = z x (c - pivot) is the
  velocity of c under a positive rotation about +z, so opening is a positive rotation about `direction`.
- joint=None: over the last frames with `min_points` points (as many as the longer window allows), a
  yaw change of the box > 3 deg (box orientation modulo 90 deg, so a box whose longest side switches
  does not count) with non-parallel midlines means revolute, anything else prismatic.
- confidence = min(1, points / 1000) * min(1, travel / (3 min_travel_m)), times min(1, midline angle /
  10 deg) for a revolute joint; residual_m = RMS distance of the end points to their box's surface.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from deploy.geometry.boxes import yaw_box
from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.types import Axis, AxisResult, Box, JointType, NoAxis

_Z = np.array([0.0, 0.0, 1.0])
_FULL_TRUST_ANGLE_DEG = 10.0
_FULL_TRUST_TRAVELS = 3.0


class PaperOBBEstimator(AxisEstimator):
    """The paper's box-based estimator (see the module docstring for the rules)."""

    name = "paper-obb"
    box_moving_part = True

    def __init__(
        self,
        min_points: int = 200,
        min_travel_m: float = 0.01,
        prismatic_min_points: int = 1000,
        prismatic_max_frames: int = 10,
        revolute_min_side_ratio: float = 1.2,
        revolute_max_frames: int = 8,
        min_midline_angle_deg: float = 1.0,
        revolute_min_yaw_deg: float = 3.0,
        n_angles: int | None = 120,
    ) -> None:
        self.min_points = min_points
        self.min_travel_m = min_travel_m
        self.prismatic_min_points = prismatic_min_points
        self.prismatic_max_frames = prismatic_max_frames
        self.revolute_min_side_ratio = revolute_min_side_ratio
        self.revolute_max_frames = revolute_max_frames
        self.min_midline_angle_deg = min_midline_angle_deg
        self.revolute_min_yaw_deg = revolute_min_yaw_deg
        self.n_angles = n_angles

    def estimate(self, window: Sequence[Observation], joint: JointType | None = None) -> AxisResult:
        if len(window) == 0:
            return NoAxis("no observations yet")
        frames = _Frames(window, self.n_angles)
        last = frames.last
        n_end = frames.count(last)
        if n_end < self.min_points:
            return NoAxis(
                f"not enough motion yet: the moving part has {n_end} of {self.min_points} points",
                {"points": n_end},
            )
        if joint is None:
            joint = self._classify(frames)
        if joint is JointType.PRISMATIC:
            enough = max(self.prismatic_min_points, self.min_points)
            start = frames.window_start(self.prismatic_max_frames, lambda i: frames.count(i) >= enough)
        else:
            start = frames.window_start(self.revolute_max_frames, lambda i: frames.count(i) >= self.min_points
                                        and _side_ratio(frames.box(i)) >= self.revolute_min_side_ratio)
        b_st, b_ed = frames.box(start), frames.box(last)
        step = b_ed.center - b_st.center
        travel = float(np.linalg.norm(step[:2]))
        details = {"joint": joint.value, "frames": last - start + 1, "points": n_end, "travel_m": travel}
        if travel < max(self.min_travel_m, 1e-9):
            return NoAxis(
                f"not enough motion yet: the moving part travelled {1000 * travel:.0f} mm of "
                f"{1000 * self.min_travel_m:.0f} mm",
                details,
            )
        confidence = min(1.0, n_end / max(self.prismatic_min_points, 1)) * min(
            1.0, travel / (_FULL_TRUST_TRAVELS * max(self.min_travel_m, 1e-9)))
        residual = _rms_to_surface(b_ed, frames.points(last))
        if joint is JointType.PRISMATIC:
            direction = np.array([step[0], step[1], 0.0]) / travel
            return Axis(JointType.PRISMATIC, b_st.center.copy(), direction, confidence, residual)
        angle = _midline_angle_deg(b_st, b_ed)
        if angle < self.min_midline_angle_deg:
            return NoAxis("midlines parallel: not enough rotation yet", {**details, "angle_deg": angle})
        pivot = _midline_crossing(b_st, b_ed)
        sign = 1.0 if np.cross(pivot - b_st.center, _Z) @ step >= 0 else -1.0
        confidence *= min(1.0, angle / _FULL_TRUST_ANGLE_DEG)
        return Axis(JointType.REVOLUTE, pivot, sign * _Z, confidence, residual)

    def _classify(self, frames: _Frames) -> JointType:
        longest = max(self.prismatic_max_frames, self.revolute_max_frames)
        start = frames.window_start(longest, lambda i: frames.count(i) >= self.min_points)
        b_st, b_ed = frames.box(start), frames.box(frames.last)
        turn = np.mod(_yaw(b_ed) - _yaw(b_st), np.pi / 2)
        turn_deg = np.degrees(min(turn, np.pi / 2 - turn))
        turning = turn_deg > self.revolute_min_yaw_deg
        if turning and _midline_angle_deg(b_st, b_ed) >= self.min_midline_angle_deg:
            return JointType.REVOLUTE
        return JointType.PRISMATIC


class _Frames:
    """The window's finite moving-part points and their yaw boxes, computed on demand."""

    def __init__(self, window: Sequence[Observation], n_angles: int | None) -> None:
        self._window = window
        self._n_angles = n_angles
        self._points: dict[int, np.ndarray] = {}
        self._boxes: dict[int, Box] = {}
        self.last = len(window) - 1

    def points(self, i: int) -> np.ndarray:
        if i not in self._points:
            moving = np.asarray(self._window[i].moving, dtype=np.float64).reshape(-1, 3)
            self._points[i] = moving[np.all(np.isfinite(moving), axis=1)]
        return self._points[i]

    def count(self, i: int) -> int:
        return len(self.points(i))

    def box(self, i: int) -> Box:
        if i not in self._boxes:
            self._boxes[i] = yaw_box(self.points(i), self._n_angles)
        return self._boxes[i]

    def window_start(self, max_frames: int, grows: Callable[[int], bool]) -> int:
        """Oldest frame of the window ending at the newest frame: grows back while `grows(i)`."""
        start = self.last
        while start > 0 and self.last - start + 1 < max_frames and grows(start - 1):
            start -= 1
        return start


def _yaw(box: Box) -> float:
    return float(np.arctan2(box.rotation[1, 0], box.rotation[0, 0]))


def _side_ratio(box: Box) -> float:
    return float(box.extent[0] / box.extent[1]) if box.extent[1] > 0 else np.inf


def _midline_angle_deg(a: Box, b: Box) -> float:
    """Angle between the two boxes' midlines (first axes) in top view, in [0, 90] degrees."""
    u, v = a.rotation[:2, 0], b.rotation[:2, 0]
    return float(np.degrees(np.arctan2(abs(u[0] * v[1] - u[1] * v[0]), abs(u @ v))))


def _midline_crossing(a: Box, b: Box) -> np.ndarray:
    """Where the midlines cross in top view, at the height of a's centre."""
    u, v = a.rotation[:2, 0], b.rotation[:2, 0]
    s, _ = np.linalg.solve(np.column_stack([u, -v]), b.center[:2] - a.center[:2])
    return np.array([*(a.center[:2] + s * u), a.center[2]])


def _rms_to_surface(box: Box, points: np.ndarray) -> float:
    inside = np.min(box.extent / 2 - np.abs(box.to_local(points)), axis=1)
    return float(np.sqrt(np.mean(np.clip(inside, 0.0, None) ** 2)))


def open_paper_obb(_argument: str, _config: object = None) -> PaperOBBEstimator:
    return PaperOBBEstimator()
