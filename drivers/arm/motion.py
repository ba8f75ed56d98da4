"""Motion code shared by every Arm: stream joint trajectories and Cartesian lines/arcs, one command per tick.

`on_tick(state, t)` is called after every control tick with the measured state and the time since
the motion started (e.g. to grab camera frames). Returning False stops the motion: the reference
then brakes with the motion's own jerk-limited limits (along the same path for Cartesian motions),
on_tick keeps being called during braking, and its return value is ignored from then on.
Any exception while streaming stops the arm before it propagates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum
from typing import Protocol

import numpy as np
import pinocchio as pin

from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.trajectory import JointTrajectory, MotionLimits, OnlineRetargeter, PathProfile, joint_trajectory
from drivers.arm.wrench import WrenchEstimator
from drivers.errors import ArmError, IKError, JointSpeedError

OnTick = Callable[[ArmState, float], bool | None]
PathFn = Callable[[float], np.ndarray]

START_TOLERANCE_M = 0.01  # a Cartesian path must start this close to the measured tool position
TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD = 1e-6, 1e-5  # per-tick IK: tight, so commands stay smooth
RETIME_TRIES, ACCELERATION_SHARE = 3, 0.9  # a Cartesian plan is slowed by half up to this often while its joints
# would accelerate past this share of the arm's limits
POSTURE_GAIN_PER_S = 1.0  # per-tick IK: null-space pull toward the rest posture, 1/s at the path's top speed
TANGENT_STEP = 1e-4  # compliant pulls: the path's tangent from poses this far (m or rad) either side of s
STALL_SCALE = 0.02  # compliant pulls: a path slowed below this share of its speed is held still (braking
# goes on at least this fast, so that it ends)
RELEASE_SPEED_SHARE, RELEASE_JERK_PER_ACCELERATION = 0.2, 100.0  # easing back after a force stop ...
PROGRESS_SHARE = 0.01  # compliant pulls: progress counts in steps of this share of the path
SCALE_RISE_PER_S = 2.0  # compliant pulls: the force bound gives the path its speed back this slowly
HELD_FORCE_S = 0.1  # compliant pulls: the force held before the pull is the mean over this long at rest (one reading
# of motor-current joint torques is a few newtons off at the tool; the mean of 24 is a fifth of that)


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
    peak_force_n: float = 0.0  # compliant pulls: the largest force the pull added (N, filtered)
    max_offset_m: float = 0.0  # compliant pulls: how far the path yielded at most (m)
    across_force_n: float = 0.0  # compliant pulls: the largest force it added across the path (N)

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


def arc_path(T_start: np.ndarray, axis_origin: np.ndarray, axis_direction: np.ndarray, turn: bool = True) -> PathFn:
    """Tool poses rotated by s radians (right-handed) about an axis: position and orientation turn together, as a
    gripper holding a door handle does; with `turn=False` the orientation stays (a handle that turns between the
    fingers)."""
    T_start = _pose(T_start)
    c = np.asarray(axis_origin, float)
    u = _unit(axis_direction, "arc axis direction")

    def pose(s: float) -> np.ndarray:
        R = pin.exp3(s * u)
        T = np.eye(4)
        T[:3, :3] = R @ T_start[:3, :3] if turn else T_start[:3, :3]
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
    compliance: Compliance | None = None,
) -> PathResult:
    """Move the tool along path_fn(s), s in [0, length], with a jerk-limited profile of s and IK every tick.

    `profile_limits` are scalar limits on s (m or rad per s^n). Each tick's IK (`Kinematics.track`) moves
    no joint faster than its velocity limit and, in proportion to the path speed, pulls the arm's
    redundancy toward `q_rest` (default: the start configuration) and away from joint limits. Before
    moving, the path must start at the measured tool position and every tick of it must be solvable that
    way: ArmError otherwise ("ik: ..." naming where), with the arm untouched. A tracking error (commanded
    vs measured tool position) above `max_tracking_error_m` means the arm is blocked: the motion brakes
    along the path and reports reason "blocked: ...". `sample_every` ticks go into the PathResult.
    With `compliance` (and an arm that measures joint torques) the pull yields and is force-bounded
    (`CompliantPull`): the ticks are re-solved online around the checked path.
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
    track = Tracker(kin, path_fn, length, q_rest, kin.v_max * dt, POSTURE_GAIN_PER_S * dt,
                     float(profile.limits.v_max) * dt)
    profile, plan_s, plan_q = _plan_within_acceleration(track, profile, dt, q, arm.limits.a_max)
    if compliance is not None and arm.state().tau is not None:
        motion: PathMotion = CompliantPull(arm, kin, track, profile, compliance)
    else:
        motion = PlannedPath(track, profile, plan_s, plan_q, dt)
    return run_ticks(arm, kin, motion, on_tick, max_tracking_error_m, sample_every)


def _plan_within_acceleration(track: Tracker, profile: PathProfile, dt: float, q: np.ndarray, a_max: np.ndarray
                              ) -> tuple[PathProfile, np.ndarray, np.ndarray]:
    """(profile, s, joints) of the path's ticks from joints q at rest: the profile as given, or slowed by half up to
    RETIME_TRIES times while the per-tick IK's joints would accelerate past ACCELERATION_SHARE of `a_max` or move
    faster than their velocity limits (JointSpeedError): near a singularity they do, though the path's own profile is
    smooth, and the arm's safety layer would stop the motion. IKError naming the joint when even the slowest exceeds
    them."""
    for attempt in range(RETIME_TRIES + 1):
        try:
            s, qs = track.plan(profile, dt, q)
        except JointSpeedError:
            if attempt == RETIME_TRIES:
                raise
            profile = _slower(profile)
            continue
        velocity = np.diff(np.vstack([q, q, qs]), axis=0) / dt  # from rest
        ratio = np.abs(np.diff(velocity, axis=0)) / (dt * ACCELERATION_SHARE * np.asarray(a_max, float))
        if len(qs) == 0 or ratio.max() <= 1.0:
            return profile, s, qs
        if attempt < RETIME_TRIES:
            profile = _slower(profile)
    k, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    needed = ratio[k, j] * ACCELERATION_SHARE * a_max[j]
    raise IKError(f"ik: the path needs joint {track.kin.joint_names[j]} to accelerate at {needed:.1f} rad/s^2 "
                  f"(limit {a_max[j]:.1f}) at s = {s[k]:.4f} of {track.length:.4f}, even at 1/{2 ** RETIME_TRIES} of "
                  "its speed: it passes near a singularity; start from another arm configuration or shorten the path")


def _slower(profile: PathProfile) -> PathProfile:
    """The same path at half the speed (a quarter of the acceleration, an eighth of the jerk: the same shape)."""
    v, a, j = (float(x) for x in (profile.limits.v_max, profile.limits.a_max, profile.limits.j_max))
    return PathProfile(profile.length, v / 2, a / 4, j / 8)


class PathMotion(Protocol):
    """One Cartesian motion tick by tick (`run_ticks`): `tick` gives the next command and the pose it aims at,
    `check` judges the measured state; `done`, `outcome` and `reason` say where it stands."""

    done: bool
    outcome: Outcome
    reason: str
    path_fn: PathFn

    def tick(self, k: int, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """Tick k at time t from commanded joints q: (joints, joint velocities, s, commanded tool pose)."""

    def check(self, state: ArmState, t: float, error_m: float, max_error_m: float, keep_going: bool) -> None:
        """After the tick: the measured state, the tracking error, whether on_tick lets it go on."""

    def forces(self) -> tuple[float, float, float]:
        """(peak force N, largest offset m, largest force across the path N) for the PathResult."""


def run_ticks(arm: Arm, kin: Kinematics, motion: PathMotion, on_tick: OnTick | None, max_tracking_error_m: float,
              sample_every: int) -> PathResult:
    """The control-tick loop of every Cartesian motion: command, wait for the tick, measure, call on_tick, let the
    motion judge; a sample every `sample_every` ticks and at the last. Any exception stops the arm."""
    dt = arm.control_period_s
    q = arm.state().q
    samples: list[tuple[float, float, np.ndarray, np.ndarray]] = []
    max_error, k = 0.0, 0
    try:
        while not motion.done:
            k += 1
            t = k * dt
            q_next, dq, s, T = motion.tick(k, t, q)
            arm.command(q_next, dq)
            arm.sync()
            q = q_next
            state = arm.state()
            T_measured = kin.fk(state.q)
            error = float(np.linalg.norm(T[:3, 3] - T_measured[:3, 3]))
            max_error = max(max_error, error)
            keep_going = on_tick is None or on_tick(state, t) is not False
            motion.check(state, t, error, max_tracking_error_m, keep_going)
            if motion.done or k % sample_every == 0:
                samples.append((t, s, T, T_measured))
    except BaseException:
        arm.stop()
        raise
    if not samples:
        samples.append((0.0, 0.0, motion.path_fn(0.0), kin.fk(arm.state().q)))
    t_s, s_s, planned, measured = (np.array(x) for x in zip(*samples, strict=True))
    return PathResult(t_s, s_s, planned, measured, motion.outcome, motion.reason, max_error, float(s_s[-1]),
                      *motion.forces())


class PlannedPath:
    """A Cartesian motion along its planned ticks (s and joints at every tick); blocked (tracking error) or stopped
    by on_tick, it brakes along the path with the profile's own limits, IK every tick."""

    def __init__(self, track: Tracker, profile: PathProfile, plan_s: np.ndarray, plan_q: np.ndarray,
                 dt: float) -> None:
        self.track, self.profile, self.plan_s, self.plan_q, self.dt = track, profile, plan_s, plan_q, dt
        self.path_fn = track.path_fn
        self.braking: PathProfile | None = None
        self.t_brake, self.s = 0.0, 0.0
        self.outcome, self.reason, self.done = Outcome.COMPLETED, "completed", len(plan_s) == 0

    def tick(self, k: int, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        if self.braking is None:  # the planned ticks
            self.s, q_next = self.plan_s[k - 1], self.plan_q[k - 1]
            self.done = k == len(self.plan_s)
        else:
            tau = min(t - self.t_brake, self.braking.duration)
            s_prev, self.s = self.s, self.braking.at(tau)[0]
            q_next = self.track(q, s_prev, self.s)
            self.done = tau >= self.braking.duration
        return q_next, (q_next - q) / self.dt, self.s, self.path_fn(self.s)

    def check(self, state: ArmState, t: float, error_m: float, max_error_m: float, keep_going: bool) -> None:
        if self.braking is None and (error_m > max_error_m or not keep_going):
            self.outcome = Outcome.STOPPED if not keep_going else Outcome.BLOCKED
            self.reason = self.outcome.value if not keep_going else tracking_reason(error_m, max_error_m, self.s)
            self.braking, self.t_brake, self.done = self.profile.stopping(t), t, False

    def forces(self) -> tuple[float, float, float]:
        return 0.0, 0.0, 0.0


def tracking_reason(error_m: float, limit_m: float, s: float) -> str:
    return f"blocked: tracking error {error_m * 1e3:.1f} mm > {limit_m * 1e3:.1f} mm at s = {s:.4f}"


@dataclass(frozen=True)
class Tracker:
    """Per-tick IK along one path: joint steps within `max_step` (rad), the posture taking `posture_gain`
    per tick at the path's top speed `s_step` (s per tick), proportionally less when slower."""

    kin: Kinematics
    path_fn: PathFn
    length: float
    q_rest: np.ndarray
    max_step: np.ndarray
    posture_gain: float
    s_step: float

    def __call__(self, q: np.ndarray, s_prev: float, s: float, T: np.ndarray | None = None) -> np.ndarray:
        """Joints at pose T (default path_fn(s)), one tick after joints q at s_prev; ArmError "ik: ..." if out
        of reach."""
        speed = min(1.0, abs(s - s_prev) / self.s_step)
        try:
            return self.kin.track(self.path_fn(s) if T is None else T, q, self.max_step, self.q_rest,
                                  self.posture_gain, speed, TRACKING_TOL_POS_M, TRACKING_TOL_ROT_RAD)
        except IKError as exc:
            where = f"ik: lost the Cartesian path at s = {s:.4f} of {self.length:.4f}"
            raise type(exc)(f"{where}: {str(exc).removeprefix('ik: ')}") from exc

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


@dataclass(frozen=True)
class Compliance:
    """How a pull yields to the object and how hard it may pull (the robot config's `[compliance]`, the
    force limit from the run's `[opening]`).

    Admittance: the commanded tool position gets an offset x that follows the force the object resists with
    across the path (the filtered force's component normal to the path's tangent, less `deadband_n`):
    `damping_n_s_per_m` dx/dt = -F_across - `stiffness_n_per_m` x, |x| <= `max_offset_m`. The damping is high
    because a position-controlled arm holding a handle is stiff (about 1e6 N/m): the offset is an integrator
    that must not out-run it. Force bound: past `slow_from` of `force_limit_n` the path slows down, to a
    halt at `halt_at` of it, and above that it backs off along the path (the speed changing by at most
    `stop_acceleration`), so the force settles at `halt_at` of the limit on an object that does not give.
    Held there (not progressing) for `stall_s`, or going back and forth without gaining PROGRESS_SHARE of the
    path in `no_progress_s` (a force that swings about the halt), or above the limit, the pull ends "blocked" and
    the command
    eases back to where the arm measured itself then (joint accelerations within `release_acceleration_rad_s2`),
    pressing no further. None: no force limit. The pull's force is what it adds to the force held when it began
    (the grasp's squeeze, about 20 N in simulation, is not the object's resistance), and so is the force the
    admittance follows. `torque_offset`: the joint torques' own offset, measured free (drivers/arm/wrench.py).
    """

    stiffness_n_per_m: float = 1000.0
    damping_n_s_per_m: float = 8000.0
    max_offset_m: float = 0.03
    deadband_n: float = 3.0
    filter_time_constant_s: float = 0.01
    force_limit_n: float | None = None
    slow_from: float = 0.5
    halt_at: float = 0.85
    stop_acceleration: float = 1.0  # path units: m/s^2 along a line, rad/s^2 along an arc
    stall_s: float = 0.3
    no_progress_s: float = 3.0
    release_acceleration_rad_s2: float = 5.0
    torque_offset: tuple[float, ...] | None = None

    def with_force_limit(self, force_limit_n: float | None) -> Compliance:
        return replace(self, force_limit_n=force_limit_n)

    def with_torque_offset(self, offset: np.ndarray | None) -> Compliance:
        return replace(self, torque_offset=None if offset is None else tuple(float(x) for x in offset))


class CompliantPull:
    """One compliant, force-bounded pull along `track`'s path (see `Compliance`), re-solving each tick's IK
    around the commanded position plus the admittance offset (a `PathMotion` of `run_ticks`)."""

    def __init__(self, arm: Arm, kin: Kinematics, track: Tracker, profile: PathProfile,
                 compliance: Compliance) -> None:
        self.arm, self.kin, self.track, self.profile, self.c = arm, kin, track, profile, compliance
        self.path_fn = track.path_fn
        self.wrench = WrenchEstimator(kin, compliance.filter_time_constant_s, compliance.torque_offset)
        self.offset = np.zeros(3)
        self.scale = 1.0  # path speed factor of the force bound
        self.peak_force_n = self.max_offset_m = self.across_force_n = self.pull_n = 0.0
        self.bias = self._held_force()  # held before the pull (the grasp's squeeze): not the object's resistance
        self.active, self.clock, self.s, self.still_s = profile, 0.0, 0.0, 0.0
        self.release: OnlineRetargeter | None = None
        self.q_hold, self.T = arm.state().q, self.path_fn(0.0)
        self.q_cmd, self.dq_cmd = self.q_hold, np.zeros_like(self.q_hold)
        self.outcome, self._reason, self.stopping, self.done = Outcome.COMPLETED, "completed", False, False
        self.blocked_at: tuple[float, float, float] | None = None  # force N, time held still s, s
        self.gained_s, self.gained_t = 0.0, 0.0  # how far the path has come (by PROGRESS_SHARE of it), and when

    @property
    def reason(self) -> str:
        """How it ended; a force stop is named once the command has stopped (the peak includes the stop)."""
        return self._reason if self.blocked_at is None else self._force_reason(*self.blocked_at)

    def tick(self, k: int, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        dt = self.arm.control_period_s
        if self.release is None:
            self.clock += dt * (max(self.scale, STALL_SCALE) if self.stopping else self._speed(self.active, self.clock))
            self.clock = max(self.clock, 0.0)
            s_prev, self.s = self.s, self.active.at(self.clock)[0]
            self.done = self.clock >= self.active.duration
            self.T = self.path_fn(self.s)
            self.T[:3, 3] += self.offset
            dq = (self.track(q, s_prev, self.s, self.T) - q) / dt
            most = ACCELERATION_SHARE * self.arm.limits.a_max * dt  # the re-solved ticks are not the checked plan:
            dq = np.clip(dq, self.dq_cmd - most, self.dq_cmd + most)  # their joints speed up within the limits
            q_next = q + dq * dt
        else:
            q_next, dq, _ = self.release.step(self.q_hold)
            self.done = self.release.finished
        self.q_cmd, self.dq_cmd = q_next, dq
        return q_next, dq, self.s, self.T

    def check(self, state: ArmState, t: float, error_m: float, max_error_m: float, keep_going: bool) -> None:
        force = self._feel(state, self.s, self.release is None)
        self.still_s = self.still_s + self.arm.control_period_s if self.scale < STALL_SCALE else 0.0
        if self.s >= self.gained_s + PROGRESS_SHARE * self.profile.length:
            self.gained_s, self.gained_t = self.s, t
        held_s = self.still_s if self.still_s >= self.c.stall_s else t - self.gained_t
        stuck = self.still_s >= self.c.stall_s or held_s >= self.c.no_progress_s
        if self.stopping:
            return
        limit = self.c.force_limit_n
        if limit is not None and (force > limit or stuck):
            self.outcome, self.blocked_at = Outcome.BLOCKED, (force, held_s, self.s)
            self.release, self.q_hold, self.done = self._release(self.q_cmd, self.dq_cmd), state.q, False
        elif error_m > max_error_m or not keep_going:
            self.outcome = Outcome.STOPPED if not keep_going else Outcome.BLOCKED
            self._reason = self.outcome.value if not keep_going else tracking_reason(error_m, max_error_m, self.s)
            self.active, self.clock, self.done = self.active.stopping(self.clock), 0.0, False
        self.stopping = self.outcome is not Outcome.COMPLETED

    def forces(self) -> tuple[float, float, float]:
        return self.peak_force_n, self.max_offset_m, self.across_force_n

    def _held_force(self) -> np.ndarray:
        """The force the tool holds before the pull (the grasp's squeeze: not the object's resistance), the mean
        over HELD_FORCE_S at rest; the wrench filter starts from it."""
        states = []
        for _ in range(max(1, round(HELD_FORCE_S / self.arm.control_period_s))):
            self.arm.sync()
            states.append(self.arm.state())
        self.wrench.start(states)
        return self.wrench.force

    def _feel(self, state: ArmState, s: float, admit: bool) -> float:
        """Fold in the measured torques; update the admittance offset; the pull's force (N): how far the filtered
        force has changed since the pull began."""
        self.wrench.update(state)
        force = self.wrench.force
        self.pull_n = float(np.linalg.norm(force - self.bias))
        self.peak_force_n = max(self.peak_force_n, self.pull_n)
        if admit:
            tangent = self._tangent(s)
            added = force - self.bias
            across = added - (added @ tangent) * tangent
            size = float(np.linalg.norm(across))
            self.across_force_n = max(self.across_force_n, size)
            across *= max(size - self.c.deadband_n, 0.0) / size if size > 1e-9 else 0.0
            dt = self.arm.control_period_s
            self.offset += dt * (-across - self.c.stiffness_n_per_m * self.offset) / self.c.damping_n_s_per_m
            size = float(np.linalg.norm(self.offset))
            if size > self.c.max_offset_m:
                self.offset *= self.c.max_offset_m / size
            self.max_offset_m = max(self.max_offset_m, min(size, self.c.max_offset_m))
        return self.pull_n

    def _speed(self, active: PathProfile, clock: float) -> float:
        """The path-speed factor this tick: 1 below `slow_from` of the force limit, 0 at `halt_at` of it, negative
        (backing off) above, the path's speed changing by at most `stop_acceleration` per second."""
        limit = self.c.force_limit_n
        if limit is None:
            return 1.0
        slow_from, halt_at = self.c.slow_from * limit, self.c.halt_at * limit
        wanted = float(np.clip((halt_at - self.pull_n) / max(halt_at - slow_from, 1e-9), -1.0, 1.0))
        speed = abs(active.at(clock)[1])
        dt = self.arm.control_period_s
        down = self.c.stop_acceleration * dt / max(speed, 1e-9)
        self.scale = float(np.clip(wanted, self.scale - down, self.scale + min(down, SCALE_RISE_PER_S * dt)))
        return self.scale

    def _tangent(self, s: float) -> np.ndarray:
        """The path's unit tangent at s."""
        p0, p1 = self.track.path_fn(s - TANGENT_STEP)[:3, 3], self.track.path_fn(s + TANGENT_STEP)[:3, 3]
        return (p1 - p0) / max(float(np.linalg.norm(p1 - p0)), 1e-12)

    def _release(self, q_cmd: np.ndarray, dq_cmd: np.ndarray) -> OnlineRetargeter:
        """Stop the command (at q_cmd, moving at dq_cmd) as fast as the joints may: it presses no further."""
        a = self.c.release_acceleration_rad_s2
        limits = MotionLimits(self.kin.v_max * RELEASE_SPEED_SHARE, a, RELEASE_JERK_PER_ACCELERATION * a)
        return OnlineRetargeter(q_cmd, limits, self.arm.control_period_s, dq_cmd)

    def _force_reason(self, force_n: float, still_s: float, s: float) -> str:
        limit = self.c.force_limit_n
        held = f" held the path still for {still_s:.1f} s" if force_n <= (limit or 0.0) else f" > limit {limit:.0f} N"
        return f"blocked: pull force {force_n:.1f} N{held} at s = {s:.4f}, peak {self.peak_force_n:.1f} N"
