"""Motion code shared by every Arm: stream joint trajectories and Cartesian lines/arcs, one command per tick.

`on_tick(state, t)` is called after every control tick with the measured state and the time since
the motion started (e.g. to grab camera frames). Returning False stops the motion: the reference
then brakes with the motion's own jerk-limited limits (along the same path for Cartesian motions),
on_tick keeps being called during braking, and its return value is ignored from then on.
Any exception while streaming stops the arm before it propagates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.trajectory import JointTrajectory, MotionLimits, PathProfile, joint_trajectory
from drivers.errors import ArmError

OnTick = Callable[[ArmState, float], bool | None]
PathFn = Callable[[float], np.ndarray]

START_TOLERANCE_M = 0.01  # a Cartesian path must start this close to the measured tool position
TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD = 1e-6, 1e-5  # per-tick IK: tight, so commands stay smooth


@dataclass(frozen=True)
class PathResult:
    """How a Cartesian motion went, sampled every few ticks (and at the last one).

    `planned` and `measured` are tool poses (N, 4, 4): commanded, and FK of the measured joints.
    `reason` is "completed", "stopped by on_tick" or "blocked: ..." (tracking error over the limit).
    """

    t: np.ndarray
    s: np.ndarray
    planned: np.ndarray
    measured: np.ndarray
    stopped_early: bool
    reason: str
    max_tracking_error_m: float
    s_reached: float


def follow_joint_trajectory(arm: Arm, traj: JointTrajectory, on_tick: OnTick | None = None) -> bool:
    """Stream `traj` to the arm; True if it ran to the end, False if on_tick stopped it."""
    dt = arm.control_period_s
    active, t_active, stopping = traj, 0.0, False
    k = 0
    try:
        while active.duration > 0:
            k += 1
            t = k * dt
            tau = min(t - t_active, active.duration)
            q, dq, _ = active.at(tau)
            arm.command(q, dq)
            arm.sync()
            if on_tick is not None and on_tick(arm.state(), t) is False and not stopping:
                active, t_active, stopping = active.stopping(tau), t, True
            elif tau >= active.duration:
                break
    except BaseException:
        arm.stop()
        raise
    return not stopping


def move_to_joints(arm: Arm, q_goal: np.ndarray, limits: MotionLimits, on_tick: OnTick | None = None) -> bool:
    """Jerk-limited joint move from the measured position (at rest) to q_goal; True unless on_tick stopped it.

    Motions end at rest, so starting from rest keeps measured-velocity noise out of the plan.
    """
    return follow_joint_trajectory(arm, joint_trajectory(arm.state().q, q_goal, limits), on_tick)


def move_to_pose(
    arm: Arm, kin: Kinematics, T_goal: np.ndarray, limits: MotionLimits, on_tick: OnTick | None = None
) -> bool:
    """IK for the tool pose T_goal (seeded at the measured joints), then a joint move (no collision check)."""
    return move_to_joints(arm, kin.ik(T_goal, arm.state().q), limits, on_tick)


def line_path(T_start: np.ndarray, direction: np.ndarray) -> PathFn:
    """Tool poses along a straight line: s metres along `direction`, orientation unchanged."""
    T_start = _pose(T_start)
    u = _unit(direction, "line direction")

    def pose(s: float) -> np.ndarray:
        T = T_start.copy()
        T[:3, 3] += s * u
        return T

    return pose


def arc_path(T_start: np.ndarray, axis_origin: np.ndarray, axis_direction: np.ndarray) -> PathFn:
    """Tool poses rotated by s radians (right-handed) about an axis: position and orientation turn
    together, as a gripper holding a door handle does."""
    T_start = _pose(T_start)
    c = np.asarray(axis_origin, float)
    u = _unit(axis_direction, "arc axis direction")

    def pose(s: float) -> np.ndarray:
        R = pin.exp3(s * u)
        T = np.eye(4)
        T[:3, :3] = R @ T_start[:3, :3]
        T[:3, 3] = c + R @ (T_start[:3, 3] - c)
        return T

    return pose


def follow_cartesian_path(
    arm: Arm,
    kin: Kinematics,
    path_fn: PathFn,
    length: float,
    profile_limits: MotionLimits,
    on_tick: OnTick | None = None,
    max_tracking_error_m: float = 0.02,
    sample_every: int = 10,
) -> PathResult:
    """Move the tool along path_fn(s), s in [0, length], with a jerk-limited profile of s and IK every tick.

    `profile_limits` are scalar limits on s (m or rad per s^n). Before moving, the path must start at the
    measured tool position and be solvable continuously (checked every `sample_every` ticks): ArmError
    otherwise, with the arm untouched. A tracking error (commanded vs measured tool position) above
    `max_tracking_error_m` means the arm is blocked: the motion brakes and reports reason "blocked: ...".
    """
    dt = arm.control_period_s
    profile = PathProfile(length, *(float(x[0]) for x in profile_limits.arrays(1)))
    q = arm.state().q
    gap = np.linalg.norm(path_fn(0.0)[:3, 3] - kin.fk(q)[:3, 3])
    if gap > START_TOLERANCE_M:
        raise ArmError(
            f"Cartesian path starts {gap * 1e3:.0f} mm from the tool (limit {START_TOLERANCE_M * 1e3:.0f} "
            "mm): move the tool to its start first (move_to_pose)"
        )
    n_check = max(2, int(np.ceil(profile.duration / (dt * sample_every))) + 1)
    q = kin.solve_path([path_fn(s) for s in np.linspace(0.0, length, n_check)], q, restarts=0)[0]

    samples: list[tuple[float, float, np.ndarray, np.ndarray]] = []
    active, t_active, stopping, reason, max_error = profile, 0.0, False, "completed", 0.0
    k = 0
    try:
        while active.duration > 0:
            k += 1
            t = k * dt
            tau = min(t - t_active, active.duration)
            s, _ = active.at(tau)
            T = path_fn(s)
            try:
                q_next = kin.ik(T, q, TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD, restarts=0)
            except ArmError as exc:
                raise ArmError(f"lost the Cartesian path at s = {s:.4f} of {length:.4f}: {exc}") from exc
            arm.command(q_next, (q_next - q) / dt)
            arm.sync()
            q = q_next
            state = arm.state()
            T_measured = kin.fk(state.q)
            error = float(np.linalg.norm(T[:3, 3] - T_measured[:3, 3]))
            max_error = max(max_error, error)
            keep_going = on_tick is None or on_tick(state, t) is not False
            done = False
            if not stopping and (error > max_tracking_error_m or not keep_going):
                reason = "stopped by on_tick" if not keep_going else (
                    f"blocked: tracking error {error * 1e3:.1f} mm > {max_tracking_error_m * 1e3:.1f} mm "
                    f"at s = {s:.4f}"
                )
                active, t_active, stopping = active.stopping(tau), t, True
            else:
                done = tau >= active.duration
            if done or k % sample_every == 0:
                samples.append((t, s, T, T_measured))
            if done:
                break
    except BaseException:
        arm.stop()
        raise
    if not samples:
        T = path_fn(0.0)
        samples.append((0.0, 0.0, T, kin.fk(arm.state().q)))
    t_s, s_s, planned, measured = (np.array(x) for x in zip(*samples, strict=True))
    return PathResult(t_s, s_s, planned, measured, stopping, reason, max_error, float(s_s[-1]))


def _pose(T: np.ndarray) -> np.ndarray:
    T = np.asarray(T, float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"a tool pose must be a finite 4x4 transform, got shape {T.shape}")
    return T.copy()


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    v = np.asarray(v, float)
    n = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
    if not np.isfinite(n) or n < 1e-9:
        raise ValueError(f"{name} must be a finite non-zero 3-vector, got {v}")
    return v / n
