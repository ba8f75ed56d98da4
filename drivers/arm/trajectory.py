"""Jerk-limited trajectories with Ruckig: joint moves, path-parameter profiles and online retargeting.

Ruckig's community version has no intermediate waypoints offline, so Cartesian lines and arcs are
followed with a 1-DoF profile of the path parameter (`PathProfile`) and IK at every control tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import (
    ControlInterface,
    InputParameter,
    OutputParameter,
    Result,
    Ruckig,
    Synchronization,
    Trajectory,
)


@dataclass(frozen=True)
class MotionLimits:
    """Velocity, acceleration and jerk limits (per joint arrays or scalars; rad or m, per s^n)."""

    v_max: np.ndarray | float
    a_max: np.ndarray | float
    j_max: np.ndarray | float

    def arrays(self, dof: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(v_max, a_max, j_max) broadcast to `dof` values; raises ValueError unless all are finite > 0."""
        limits = (self.v_max, self.a_max, self.j_max)
        out = tuple(np.broadcast_to(np.asarray(x, float), (dof,)).copy() for x in limits)
        if not all(np.all(np.isfinite(x) & (x > 0)) for x in out):
            raise ValueError(f"motion limits must be finite and positive, got {self}")
        return out


def _input(
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    limits: MotionLimits,
) -> InputParameter:
    dof = len(position)
    inp = InputParameter(dof)
    inp.current_position = position
    inp.current_velocity = velocity
    inp.current_acceleration = acceleration
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = limits.arrays(dof)
    return inp


def _calculate(inp: InputParameter) -> Trajectory:
    trajectory = Trajectory(inp.degrees_of_freedom)
    result = Ruckig(inp.degrees_of_freedom).calculate(inp, trajectory)
    if result != Result.Working:
        raise ValueError(f"Ruckig could not plan ({result.name}): check the start state, target and limits")
    return trajectory


def _finite(name: str, x: np.ndarray | None, dof: int) -> np.ndarray:
    x = np.zeros(dof) if x is None else np.asarray(x, float)
    if x.shape != (dof,) or not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be {dof} finite values, got {x}")
    return x


class JointTrajectory:
    """A time-optimal jerk-limited joint motion; sample it with `at(t)` for t in [0, duration]."""

    def __init__(self, trajectory: Trajectory, limits: MotionLimits) -> None:
        self._trajectory = trajectory
        self.limits = limits
        self.duration = float(trajectory.duration)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, dq, ddq) at time t (clamped to the trajectory)."""
        q, dq, ddq = self._trajectory.at_time(float(np.clip(t, 0.0, self.duration)))
        return np.array(q), np.array(dq), np.array(ddq)

    def stopping(self, t: float) -> JointTrajectory:
        """The quickest jerk-limited stop from this trajectory's state at time t (starts at t = 0)."""
        q, dq, ddq = self.at(t)
        inp = _input(q, dq, ddq, self.limits)
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity = np.zeros(len(q))
        inp.target_acceleration = np.zeros(len(q))
        return JointTrajectory(_calculate(inp), self.limits)


def joint_trajectory(
    q0: np.ndarray, q1: np.ndarray, limits: MotionLimits, dq0: np.ndarray | None = None
) -> JointTrajectory:
    """Rest-to-rest (or from velocity dq0) motion from q0 to q1, phase-synchronised when possible so
    that all joints move along a straight line in joint space."""
    q0 = _finite("start position q0", q0, len(q0))
    dof = len(q0)
    inp = _input(q0, _finite("start velocity dq0", dq0, dof), np.zeros(dof), limits)
    inp.target_position = _finite("goal position q1", q1, dof)
    inp.synchronization = Synchronization.Phase
    return JointTrajectory(_calculate(inp), limits)


class PathProfile:
    """A jerk-limited 1-DoF profile of the path parameter s from 0 to `length` (m or rad), rest to rest.

    `at(t)` gives (s, ds); follow a Cartesian path by evaluating pose(s) and solving IK each tick.
    """

    def __init__(self, length: float, v_max: float, a_max: float, j_max: float) -> None:
        if not np.isfinite(length) or length < 0:
            raise ValueError(f"path length must be finite and >= 0, got {length}")
        limits = MotionLimits(float(v_max), float(a_max), float(j_max))
        inp = _input(np.zeros(1), np.zeros(1), np.zeros(1), limits)
        inp.target_position = [float(length)]
        self._init(_calculate(inp), limits, float(length))

    def _init(self, trajectory: Trajectory, limits: MotionLimits, length: float) -> None:
        self._trajectory = trajectory
        self.limits = limits
        self.length = length
        self.duration = float(trajectory.duration)

    def _state(self, t: float) -> tuple[float, float, float]:
        s, ds, dds = self._trajectory.at_time(float(np.clip(t, 0.0, self.duration)))
        return s[0], ds[0], dds[0]

    def at(self, t: float) -> tuple[float, float]:
        """(s, ds/dt) at time t (clamped to the profile; s clamped to [0, length])."""
        s, ds, _ = self._state(t)
        return float(np.clip(s, 0.0, self.length)), ds

    def stopping(self, t: float) -> PathProfile:
        """The quickest jerk-limited stop from the state at time t, as a profile starting at t = 0 that
        continues along the same path (its s values are on this path's scale)."""
        s, ds, dds = self._state(t)
        inp = _input(np.array([s]), np.array([ds]), np.array([dds]), self.limits)
        inp.control_interface = ControlInterface.Velocity
        inp.target_velocity = [0.0]
        inp.target_acceleration = [0.0]
        profile = PathProfile.__new__(PathProfile)
        profile._init(_calculate(inp), self.limits, self.length)
        return profile


class OnlineRetargeter:
    """Online Ruckig: each control cycle, one jerk-limited step toward a target that may change.

    `step(q_target)` returns the next (q, dq, ddq) to command, `control_period_s` after the last one.
    """

    def __init__(
        self, q0: np.ndarray, limits: MotionLimits, control_period_s: float, dq0: np.ndarray | None = None
    ) -> None:
        q0 = _finite("start position q0", q0, len(q0))
        self.dof = len(q0)
        self._otg = Ruckig(self.dof, float(control_period_s))
        self._input = _input(q0, _finite("start velocity dq0", dq0, self.dof), np.zeros(self.dof), limits)
        self._input.target_position = q0
        self._output = OutputParameter(self.dof)
        self.finished = True

    def step(
        self, q_target: np.ndarray, dq_target: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Move one cycle toward q_target (reached with velocity dq_target, default 0)."""
        self._input.target_position = _finite("target position", q_target, self.dof)
        self._input.target_velocity = _finite("target velocity", dq_target, self.dof)
        result = self._otg.update(self._input, self._output)
        if result not in (Result.Working, Result.Finished):
            raise ValueError(f"Ruckig could not retarget ({result.name}); check the target and limits")
        self._output.pass_to_input(self._input)
        self.finished = result == Result.Finished
        out = self._output
        return np.array(out.new_position), np.array(out.new_velocity), np.array(out.new_acceleration)
