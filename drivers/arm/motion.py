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
from enum import Enum

import numpy as np
import pinocchio as pin

from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.trajectory import JointTrajectory, MotionLimits, PathProfile, joint_trajectory
from drivers.errors import ArmError, IKError

OnTick = Callable[[ArmState, float], bool | None]
PathFn = Callable[[float], np.ndarray]

START_TOLERANCE_M = 0.01  # a Cartesian path must start this close to the measured tool position
TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD = 1e-6, 1e-5  # per-tick IK: tight, so commands stay smooth
POSTURE_GAIN_PER_S = 1.0  # per-tick IK: null-space pull toward the rest posture, 1/s at the path's top speed


class Outcome(Enum):
    """How a Cartesian motion ended."""

    COMPLETED = "completed"
    STOPPED = "stopped by on_tick"
    BLOCKED = "blocked"  # the tracking error exceeded its limit: something holds the tool back


@dataclass(frozen=True)
class PathResult:
    """How a Cartesian motion went, sampled every few ticks (and at the last one).

    `planned` and `measured` are tool poses (N, 4, 4): commanded, and FK of the measured joints.
    `reason` describes the `outcome` ("blocked: tracking error ... at s = ...").
    """

    t: np.ndarray
    s: np.ndarray
    planned: np.ndarray
    measured: np.ndarray
    outcome: Outcome
    reason: str
    max_tracking_error_m: float
    s_reached: float

    @property
    def stopped_early(self) -> bool:
        return self.outcome is not Outcome.COMPLETED


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
    q_rest: np.ndarray | None = None,
) -> PathResult:
    """Move the tool along path_fn(s), s in [0, length], with a jerk-limited profile of s and IK every tick.

    `profile_limits` are scalar limits on s (m or rad per s^n). Each tick's IK (`Kinematics.track`) moves
    no joint faster than its velocity limit and, in proportion to the path speed, pulls the arm's
    redundancy toward `q_rest` (default: the start configuration) and away from joint limits. Before
    moving, the path must start at the measured tool position and every tick of it must be solvable that
    way: ArmError otherwise ("ik: ..." naming where), with the arm untouched. A tracking error (commanded
    vs measured tool position) above `max_tracking_error_m` means the arm is blocked: the motion brakes
    along the path and reports reason "blocked: ...". `sample_every` ticks go into the PathResult.
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
    q_rest = q.copy() if q_rest is None else np.asarray(q_rest, float)
    track = _Tracker(kin, path_fn, length, q_rest, kin.v_max * dt, POSTURE_GAIN_PER_S * dt,
                     float(profile.limits.v_max) * dt)
    plan_s, plan_q = track.plan(profile, dt, q)

    samples: list[tuple[float, float, np.ndarray, np.ndarray]] = []
    braking: PathProfile | None = None
    t_brake, s, outcome, reason, max_error = 0.0, 0.0, Outcome.COMPLETED, "completed", 0.0
    k, done = 0, len(plan_s) == 0
    try:
        while not done:
            k += 1
            t = k * dt
            if braking is None:  # the planned ticks
                s, q_next = plan_s[k - 1], plan_q[k - 1]
                done = k == len(plan_s)
            else:
                tau = min(t - t_brake, braking.duration)
                s_prev, s = s, braking.at(tau)[0]
                q_next = track(q, s_prev, s)
                done = tau >= braking.duration
            arm.command(q_next, (q_next - q) / dt)
            arm.sync()
            q = q_next
            state = arm.state()
            T = path_fn(s)
            T_measured = kin.fk(state.q)
            error = float(np.linalg.norm(T[:3, 3] - T_measured[:3, 3]))
            max_error = max(max_error, error)
            keep_going = on_tick is None or on_tick(state, t) is not False
            if braking is None and (error > max_tracking_error_m or not keep_going):
                outcome = Outcome.STOPPED if not keep_going else Outcome.BLOCKED
                reason = outcome.value if not keep_going else (
                    f"blocked: tracking error {error * 1e3:.1f} mm > {max_tracking_error_m * 1e3:.1f} mm "
                    f"at s = {s:.4f}"
                )
                braking, t_brake, done = profile.stopping(t), t, False
            if done or k % sample_every == 0:
                samples.append((t, s, T, T_measured))
    except BaseException:
        arm.stop()
        raise
    if not samples:
        T = path_fn(0.0)
        samples.append((0.0, 0.0, T, kin.fk(arm.state().q)))
    t_s, s_s, planned, measured = (np.array(x) for x in zip(*samples, strict=True))
    return PathResult(t_s, s_s, planned, measured, outcome, reason, max_error, float(s_s[-1]))


@dataclass(frozen=True)
class _Tracker:
    """Per-tick IK along one path: joint steps within `max_step` (rad), the posture taking `posture_gain`
    per tick at the path's top speed `s_step` (s per tick), proportionally less when slower."""

    kin: Kinematics
    path_fn: PathFn
    length: float
    q_rest: np.ndarray
    max_step: np.ndarray
    posture_gain: float
    s_step: float

    def __call__(self, q: np.ndarray, s_prev: float, s: float) -> np.ndarray:
        """Joints at path_fn(s), one tick after joints q at s_prev; ArmError "ik: ..." if out of reach."""
        speed = min(1.0, abs(s - s_prev) / self.s_step)
        try:
            return self.kin.track(self.path_fn(s), q, self.max_step, self.q_rest, self.posture_gain, speed,
                                  TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD)
        except IKError as exc:
            where = f"ik: lost the Cartesian path at s = {s:.4f} of {self.length:.4f}"
            raise IKError(f"{where}: {str(exc).removeprefix('ik: ')}") from exc

    def plan(self, profile: PathProfile, dt: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s, joints) at every control tick of `profile` (t = dt, 2 dt, ... up to its end), from joints q."""
        n = int(np.ceil(profile.duration / dt - 1e-9))
        s = np.array([profile.at(tau)[0] for tau in np.append(np.arange(1, n) * dt, profile.duration)[:n]])
        qs = np.empty((n, len(q)))
        for k in range(n):
            qs[k] = q = self(q, s[k - 1] if k else 0.0, s[k])
        return s, qs


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
