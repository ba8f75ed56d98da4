"""The estimator interface: `estimate(window) -> Axis | NoAxis`."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from deploy.geometry.types import AxisResult, Box, JointType


@dataclass(frozen=True)
class Observation:
    """What one frame tells the estimators (base frame, metres).

    index: frame index (stable key for caches); t: seconds; moving: (N,3) moving-part points
    (already filtered); body_box: the first frame's body box (handle removed); gripper_pose: 4x4 pose
    of the gripper from forward kinematics, None when no arm is attached (recordings without poses).
    """

    index: int
    t: float
    moving: np.ndarray
    body_box: Box
    gripper_pose: np.ndarray | None = None


class AxisEstimator(ABC):
    """Estimates the joint axis from a window of observations, oldest first.

    `joint=None` asks the estimator to classify the joint type itself. Estimators decide from what a
    robot senses whether there is enough motion, and return `NoAxis(reason)` when there is not;
    they never raise on degenerate input and never return NaN.
    """

    name: str
    use_gripper: bool = False  # whether it reads the gripper's path (the observations' gripper poses)
    box_moving_part: bool = False  # whether its rules take the moving part as what left the first frame's object box
    # (the paper's); `[geometry] moving_part = "auto"` gives it that one, the others what left the static scene

    @abstractmethod
    def estimate(self, window: Sequence[Observation], joint: JointType | None = None) -> AxisResult: ...
