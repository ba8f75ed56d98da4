"""What an episode reports to as it goes (`EpisodeView`): one log line per step on the `deploy.control.steps` logger
(the CLI prints it on stderr) and, with `--view`, everything forwarded to a rerun viewer (deploy/report/viewer.py)."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from deploy.geometry.types import Axis, JointType
from drivers.arm.base import ArmState
from drivers.camera.base import Frame

if TYPE_CHECKING:
    from deploy.report.viewer import RerunViewer

STEP_LOGGER = "deploy.control.steps"

step_log = logging.getLogger(STEP_LOGGER)


class EpisodeView:
    """What an episode reports to: a log line per step, and everything to `viewer` when there is one. The
    episode calls it as it would a `RerunViewer` (frame, arm, clouds, grasp, motion, axis, close)."""

    def __init__(self, viewer: RerunViewer | None = None) -> None:
        self.viewer = viewer
        self.steps = 0
        self.motions = 0
        self._next_arm_t = -np.inf

    def frame(self, t: float, frame: Frame, mask: np.ndarray | None = None,
              tool_pose: np.ndarray | None = None) -> None:
        if self.viewer is not None:
            self.viewer.frame(t, frame, mask, tool_pose)

    @property
    def showing(self) -> bool:
        """Whether a viewer shows the episode (what only it needs is computed only then)."""
        return self.viewer is not None

    def saved_to(self) -> dict | None:
        """The viewer's file and whether a live viewer showed it ({"path", "live"}); None without a viewer."""
        return None if self.viewer is None else {"path": str(self.viewer.path), "live": self.viewer.live}

    def arm(self, t: float, state: ArmState, commanded: np.ndarray | None = None, every_s: float = 0.0) -> None:
        """The arm's measured state and command at time `t`: shown at most once per `every_s` seconds."""
        if self.viewer is not None and t >= self._next_arm_t:
            self._next_arm_t = t + every_s
            self.viewer.arm(t, state.q, commanded, state.gripper_width_m)

    def cloud(self, points: np.ndarray) -> None:
        if self.viewer is not None:
            self.viewer.cloud(points)

    def step_clouds(self, t: float, cloud: np.ndarray, moving: np.ndarray | None, handle: np.ndarray | None) -> None:
        if self.viewer is not None:
            self.viewer.step_clouds(t, cloud, moving, handle)

    def grasp(self, t: float, T_grasp: np.ndarray) -> None:
        if self.viewer is not None:
            self.viewer.grasp(t, T_grasp)

    def motion(self, t: float, label: str, planned: np.ndarray, executed: np.ndarray) -> None:
        """A motion that ended at time `t`: its planned and executed tool paths (poses)."""
        if self.viewer is not None:
            self.viewer.motion(t, self.motions, label, planned, executed)
        self.motions += 1

    def axis(self, t: float, axis: Axis, opened: float, source: str | None = None) -> None:
        """Step `steps`: its line (opening with unit, where the axis came from, confidence), then the viewer."""
        unit = "deg" if axis.joint_type is JointType.REVOLUTE else "m"
        where = f"{axis.joint_type.value} from {source}" if source else axis.joint_type.value
        step_log.info("step %d: opened %.3f %s, axis %s, confidence %.2f", self.steps, opened, unit, where,
                      axis.confidence)
        if self.viewer is not None:
            self.viewer.axis(t, axis, opened, source, self.steps)
        self.steps += 1

    def true_axis(self, axis: Axis) -> None:
        if self.viewer is not None:
            self.viewer.true_axis(axis)

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
