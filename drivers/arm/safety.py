"""The safety layer below the planner: every Arm checks each joint command here before sending it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.arm.kinematics import Kinematics
from drivers.arm.robots import RobotSpec
from drivers.errors import ArmError

RELATIVE_SLACK = 1e-6  # rounding in trajectory sampling must not trip a limit
REPLAN = "re-plan inside the joint range"
SLOWER = "lower the motion limits"


@dataclass(frozen=True)
class SafetyLimits:
    """Hard limits per joint (rad, rad/s, rad/s^2) and a box the tool position must stay in (m, base frame).

    `jump_tolerance_rad` is how far a command may step beyond v_max * dt from the previous one: it
    absorbs the gap between the measured and the last commanded position when a motion starts.
    """

    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    jump_tolerance_rad: float = 0.01

    def __post_init__(self) -> None:
        """ArmError unless every limit can hold: one value per joint, ranges not empty, no NaN (a NaN limit
        would let every command pass)."""
        for name in ("q_min", "q_max", "v_max", "a_max", "workspace_min", "workspace_max"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), float))
        dof = self.q_min.shape
        if len(dof) != 1 or any(x.shape != dof for x in (self.q_max, self.v_max, self.a_max)) \
                or self.workspace_min.shape != (3,) or self.workspace_max.shape != (3,):
            self._refuse("one value per joint for q_min, q_max, v_max and a_max, three for the workspace box")
        if not np.all(self.q_min < self.q_max):
            self._refuse("q_min must be below q_max on every joint")
        if not (np.all(self.v_max > 0) and np.all(self.a_max > 0) and self.jump_tolerance_rad >= 0):
            self._refuse("v_max and a_max must be above 0, jump_tolerance_rad 0 or more")
        if not np.all(self.workspace_min < self.workspace_max):
            self._refuse("workspace_min must be below workspace_max on every axis")

    def _refuse(self, what: str) -> None:
        raise ArmError(f"invalid safety limits: {what}; fix the URDF's limits or the robot config")

    @classmethod
    def for_robot(cls, robot: RobotSpec, kin: Kinematics) -> SafetyLimits:
        """The URDF position and velocity limits, the robot's acceleration limits and workspace box."""
        return cls(kin.q_min, kin.q_max, kin.v_max, robot.a_max, robot.workspace_min, robot.workspace_max)


class SafetyGuard:
    """Checks one joint command against `SafetyLimits`; raises ArmError naming the joint and the limit.

    Stateless: the arm passes its previous command (or, when streaming starts, the measured position)
    and, for the acceleration check, its previous velocity command.
    """

    def __init__(self, limits: SafetyLimits, joint_names: Sequence[str]) -> None:
        self.limits = limits
        self.joint_names = list(joint_names)

    def check(
        self,
        q_cmd: np.ndarray,
        dq_cmd: np.ndarray | None,
        q_prev_cmd: np.ndarray,
        dt: float,
        tool_position: np.ndarray,
        dq_prev_cmd: np.ndarray | None = None,
        q_measured: np.ndarray | None = None,
    ) -> None:
        """Raise ArmError if the command breaks a position, velocity, jump, acceleration or workspace limit.

        dq_cmd may be None (no velocity feed-forward); the acceleration check needs dq_cmd and dq_prev_cmd.
        A step is measured from the previous command or, when given and nearer, from the measured joints: a
        motion that starts where a compliant arm was pushed to (a held door) is not a jump.
        """
        lim = self.limits
        if not (np.isfinite(dt) and dt > 0):
            raise ArmError(f"safety stop: control period {dt} s is not a positive time: fix the arm's control rate")
        q = self._vector("position", q_cmd)
        step = q - self._vector("previous position", q_prev_cmd)
        if q_measured is not None:
            from_measured = q - self._vector("measured position", q_measured)
            step = np.where(np.abs(from_measured) < np.abs(step), from_measured, step)
        q_tol = RELATIVE_SLACK * (1.0 + lim.q_max - lim.q_min)
        v_max = lim.v_max * (1 + RELATIVE_SLACK)
        if (j := _worst(q - lim.q_max - q_tol)) is not None:
            self._fail(j, f"position {q[j]:.4f} rad is above its limit {lim.q_max[j]:.4f}", REPLAN)
        if (j := _worst(lim.q_min - q - q_tol)) is not None:
            self._fail(j, f"position {q[j]:.4f} rad is below its limit {lim.q_min[j]:.4f}", REPLAN)
        if dq_cmd is not None:
            dq = self._vector("velocity", dq_cmd)
            if (j := _worst(np.abs(dq) - v_max)) is not None:
                self._fail(j, f"velocity {dq[j]:.3f} rad/s exceeds its limit {lim.v_max[j]:.3f}", SLOWER)
        max_step = v_max * dt + lim.jump_tolerance_rad
        if (j := _worst(np.abs(step) - max_step)) is not None:
            self._fail(j, f"command jumps {step[j]:.4f} rad in one {dt * 1e3:.1f} ms cycle "
                       f"(limit {max_step[j]:.4f} rad)", "the planner made a discontinuous command")
        if dq_cmd is not None and dq_prev_cmd is not None:
            ddq = (dq - self._vector("previous velocity", dq_prev_cmd)) / dt
            if (j := _worst(np.abs(ddq) - lim.a_max * (1 + RELATIVE_SLACK))) is not None:
                self._fail(j, f"acceleration {ddq[j]:.2f} rad/s^2 exceeds its limit {lim.a_max[j]:.2f}",
                           SLOWER)
        p = np.asarray(tool_position, float)
        outside = ~np.isfinite(p) | (p < lim.workspace_min) | (p > lim.workspace_max)
        if outside.any():
            box = f"{np.round(lim.workspace_min, 3).tolist()} .. {np.round(lim.workspace_max, 3).tolist()} m"
            axis = "xyz"[int(np.argmax(outside))]
            raise ArmError(
                f"safety stop: tool position ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m leaves the workspace box "
                f"{box} along {axis}: re-plan inside it or widen it in the robot config"
            )

    def _vector(self, what: str, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        dof = len(self.joint_names)
        if x.shape != (dof,):
            raise ArmError(f"safety stop: {what} command has shape {x.shape}, expected ({dof},): "
                           "the planner and the arm disagree on the joints")
        if (j := _worst(np.where(np.isfinite(x), -1.0, 1.0))) is not None:
            self._fail(j, f"{what} command is not finite", "a planner or IK bug produced NaN")
        return x

    def _fail(self, joint: int, what: str, fix: str) -> None:
        raise ArmError(f"safety stop: joint {self.joint_names[joint]} {what}: {fix}")


def _worst(excess: np.ndarray) -> int | None:
    """Index of the largest positive excess over a limit, None if every value is within it."""
    return int(np.argmax(excess)) if np.max(excess) > 0 else None
