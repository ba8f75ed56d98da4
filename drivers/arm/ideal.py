"""An ideal kinematic arm: every command is reached exactly at the next tick (dry runs, motion tests)."""

from __future__ import annotations

import numpy as np

from drivers.arm.base import GRIP_FORCE_N, Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.robots import RobotSpec, panda
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.errors import ArmError


class IdealArm(Arm):
    """Kinematic arm on a simulated clock: `sync()` advances time by one control period (no sleeping)
    and moves the joints to the last command; the gripper moves toward its command at a fixed speed.

    Every command passes the SafetyGuard; a violation stops the arm and raises ArmError.
    """

    def __init__(
        self,
        kin: Kinematics,
        guard: SafetyGuard,
        q0: np.ndarray,
        control_period_s: float = 0.002,
        gripper_max_width_m: float = 0.08,
        gripper_speed_m_s: float = 0.1,
    ) -> None:
        self.kin = kin
        self.guard = guard
        self.control_period_s = control_period_s
        self.gripper_max_width_m = gripper_max_width_m
        self.gripper_speed_m_s = gripper_speed_m_s
        self._t = 0.0
        self._q = np.array(q0, float)
        self._dq = np.zeros(kin.dof)
        self._q_cmd = self._q.copy()
        self._dq_cmd: np.ndarray | None = None
        self._width = self._width_cmd = gripper_max_width_m

    @classmethod
    def for_robot(
        cls, robot: RobotSpec, q0: np.ndarray | None = None, control_period_s: float = 0.002
    ) -> IdealArm:
        """An ideal arm of this robot model with its safety limits, starting at q0 (default: ready pose)."""
        kin = Kinematics.from_robot(robot)
        guard = SafetyGuard(SafetyLimits.for_robot(robot, kin), kin.joint_names)
        q0 = robot.q_ready if q0 is None else q0
        return cls(kin, guard, q0, control_period_s, robot.gripper_max_width_m)

    @classmethod
    def panda(cls, q0: np.ndarray | None = None, control_period_s: float = 0.002) -> IdealArm:
        return cls.for_robot(panda(), q0, control_period_s)

    @property
    def joint_names(self) -> list[str]:
        return self.kin.joint_names

    def state(self) -> ArmState:
        return ArmState(self._t, self._q.copy(), self._dq.copy(), None, self._width)

    def commanded_q(self) -> np.ndarray:
        return self._q_cmd.copy()

    def command(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        try:
            self.guard.check(q, dq, self._q_cmd, self.control_period_s, self.kin.fk(q)[:3, 3], self._dq_cmd)
        except ArmError:
            self.stop()
            raise
        self._q_cmd = np.array(q, float)
        self._dq_cmd = None if dq is None else np.array(dq, float)

    def sync(self) -> None:
        dt = self.control_period_s
        self._t += dt
        q_new = self._q_cmd.copy()
        self._dq = (q_new - self._q) / dt if self._dq_cmd is None else self._dq_cmd.copy()
        self._q = q_new
        gap = self._width_cmd - self._width
        self._width += float(np.clip(gap, -self.gripper_speed_m_s * dt, self.gripper_speed_m_s * dt))

    def set_gripper(self, width_m: float, force_n: float = GRIP_FORCE_N) -> None:
        """Command the opening, clamped to [0, gripper_max_width_m]; the ideal gripper ignores force."""
        if not np.isfinite(width_m):
            raise ArmError(f"gripper width command {width_m} is not finite: a planner bug produced NaN")
        self._width_cmd = float(np.clip(width_m, 0.0, self.gripper_max_width_m))

    def stop(self) -> None:
        """Hold the current position; the next command starts a new stream (no acceleration check)."""
        self._q_cmd = self._q.copy()
        self._dq_cmd = None
        self._dq = np.zeros_like(self._q)
        self._width_cmd = self._width
