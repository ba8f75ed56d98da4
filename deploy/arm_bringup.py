"""Arm bring-up operations behind `deploy arm ...`: scan, status, enable/disable/zero, and planned joint moves
(home, jog, move to a pose) that are shown before they run, keep GOAL_MARGIN_RAD inside the joint limits and fail
unless they end on their goal; and the `--sim-fault` injections of the simulated CAN arm, which every command
that takes `--arm sim-can` offers.

The arm comes from the rig builder (`deploy.rig.build_arm`, no camera); commands that address the motors directly
(scan, disable, zero) use the arm kind's bare bus (`deploy.rig.bare_bus`: the bus factory of its registry entry).
No kind is named here: `--sim-fault` goes with the simulated kinds that have a bus (simulated motors).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from deploy.rig import bare_bus, build_arm
from drivers.arm.base import Arm
from drivers.arm.can_arm import scan_bus
from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import Special, special
from drivers.arm.disable import disable_and_confirm
from drivers.arm.disable import motor_states as disable_states
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import move_to_joints
from drivers.arm.motor_channels import MotorChannel, request_feedback
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import RobotConfig
from drivers.arm.trajectory import joint_trajectory
from drivers.errors import ArmError, IKError

if TYPE_CHECKING:
    from sim_fallback.sim_faults import SimFault

BRINGUP_SPEED = 0.2  # share of the velocity, acceleration and jerk limits used by bring-up moves
GOAL_MARGIN_RAD = 0.02  # goals keep this far inside the joint limits: a move's end overshoots by up to ~0.01 rad
GOAL_TOLERANCE_RAD = 0.01  # a move fails when a joint settles farther than this from its goal
SETTLE_S = 1.0  # after the trajectory, the joints have this long to come to rest within GOAL_TOLERANCE_RAD
SETTLED_SPEED = 0.05  # rad/s: below this (and within the tolerance) a joint counts as settled


@dataclass(frozen=True)
class Plan:
    """A joint move, as shown to the user before it runs."""

    what: str
    q_start: np.ndarray
    q_goal: np.ndarray
    duration_s: float
    tool_start: np.ndarray
    tool_goal: np.ndarray

    def to_dict(self) -> dict:
        return {"what": self.what, "q_start": self.q_start.round(4).tolist(), "q_goal": self.q_goal.round(4).tolist(),
                "duration_s": round(self.duration_s, 3), "tool_start_m": self.tool_start.round(4).tolist(),
                "tool_goal_m": self.tool_goal.round(4).tolist()}


def make_arm(kind: str, config: RobotConfig) -> Arm:
    """An arm of `kind` for the CLI, built as a rig builds its arm; ArmError for a simulated kind without simulated
    motors of its own (it lives in a simulated world, which bring-up does not build)."""
    entry, _ = ARMS.entry(kind)
    if entry.simulated and entry.bus is None:
        instead = " or ".join(f"--arm {e.usage} ({e.description})" for e in ARMS.entries()
                              if e.simulated and e.bus is not None)
        raise ArmError(f"--arm {kind} lives in a simulated world, which arm commands do not build: use {instead}")
    return build_arm(kind, config)


def fault_kinds() -> list[str]:
    """The arm kinds `--sim-fault` can break: simulated, with a bus (simulated Damiao motors answer on it)."""
    return [e.usage for e in ARMS.entries() if e.simulated and e.bus is not None]


def parse_sim_faults(kind: str, texts: list[str] | None) -> list[SimFault]:
    """The `--sim-fault` values; ConfigError when one is malformed or the arm is not the simulated CAN arm."""
    if not texts:
        return []
    from deploy.errors import ConfigError
    from sim_fallback.sim_faults import SimFault

    if kind not in fault_kinds():
        raise ConfigError(f"--sim-fault breaks the simulated CAN arm: use it with --arm {' or '.join(fault_kinds())}, "
                          f"not --arm {kind}")
    try:
        return [SimFault.parse(text) for text in texts]
    except ValueError as exc:
        raise ConfigError(f"--sim-fault {exc}") from None


def inject_sim_faults(arm: Arm, faults: list[SimFault]) -> None:
    """Schedule `faults` on the simulated motors of the sim-can `arm` (found by its CAN channel)."""
    if not faults:
        return
    from sim_fallback.can_motors import motors_on

    motors = None if arm.bus_channel is None else motors_on(arm.bus_channel)
    if motors is None:
        raise ArmError(f"no simulated motors answer on CAN channel {arm.bus_channel!r}: --sim-fault needs "
                       "--arm sim-can")
    for fault in faults:
        fault.schedule(motors)


@contextmanager
def released(arm: Arm) -> Iterator[Arm]:
    """Disconnect `arm` when an exception leaves (a CAN arm's exception then carries the motors' final states as
    `motors`: drivers/arm/can_arm.py, as `with arm:` does)."""
    try:
        yield arm
    except BaseException as exc:
        arm.__exit__(type(exc), exc, exc.__traceback__)
        raise


@contextmanager
def raw_bus(config: RobotConfig, kind: str, faults: list[SimFault] | None = None) -> Iterator[CanBus]:
    """The config's bus without an arm on top, from arm `kind`'s registry entry (a simulated kind: with its
    simulated motors answering, `faults` injected); closed after."""
    with bare_bus(kind, config) as (bus, motors):
        for fault in faults or []:
            fault.schedule(motors)
        yield bus


def scan(kind: str, config: RobotConfig, ids: range, faults: list[SimFault] | None = None) -> list[dict]:
    """Motors that answer on the config's bus (sim-can: the simulated motors of the config)."""
    with raw_bus(config, kind, faults) as bus:
        return [m.to_dict() for m in scan_bus(bus, ids)]


def status(arm: Arm) -> dict:
    """Joint positions, tool pose and, for CAN arms, each motor's report while enabled (`motors`) and state
    once damped and disabled (`motors_after_stop`: drivers/arm/disable.py). Connects: enables, then stops."""
    with arm:
        state = arm.state()
        kin = arm.kin
        tool = kin.fk(state.q)
        data = {"joint_positions_rad": dict(zip(arm.joint_names, np.round(state.q, 4).tolist(), strict=True)),
                "tool_position_m": tool[:3, 3].round(4).tolist(),
                "tool_rpy_deg": np.degrees(Rotation.from_matrix(tool[:3, :3]).as_euler("xyz")).round(2).tolist(),
                "gripper_width_m": round(state.gripper_width_m, 4)}
        if report := arm.motor_report():
            data["motors"] = report
    if after := arm.motor_states():
        data["motors_after_stop"] = after
    return data


def disable_all(config: RobotConfig, kind: str, faults: list[SimFault] | None = None) -> list[dict]:
    """Send disable to every configured motor (works without connecting) and wait for each one's answer; the
    motors' states (drivers/arm/disable.py: `enabled` where no answer came)."""
    channels = [MotorChannel(m.name, m, m.default_limits) for m in config.motors]
    with raw_bus(config, kind, faults) as bus:
        unconfirmed = disable_and_confirm(bus, channels, config.watchdog.reply_timeout_s, threading.RLock(),
                                          time.perf_counter)
    return disable_states(channels, {c.name for c in unconfirmed})


def set_zero(config: RobotConfig, kind: str, joint: str, faults: list[SimFault] | None = None) -> dict:
    """Make motor `joint`'s current position its zero: disable it (confirmed by its answer), then send set-zero
    and wait for the answer (it stores the zero). ArmError naming the motor when either goes unanswered."""
    motors = {m.name: m for m in config.motors}
    if joint not in motors:
        raise ArmError(f"joint {joint!r} is not in {config.label}: joints are {', '.join(motors)}")
    c = MotorChannel(joint, motors[joint], motors[joint].default_limits)
    timeout = config.watchdog.reply_timeout_s
    fix = "check its power, CAN id, master id and the bus bitrate (`deploy arm scan` lists the ids that answer)"
    with raw_bus(config, kind, faults) as bus:
        if disable_and_confirm(bus, [c], timeout, threading.RLock(), time.perf_counter):
            raise ArmError(f"motor {c.describe()} did not answer the disable: not zeroed (it may still be enabled); "
                           f"{fix}")
        try:
            request_feedback(bus, c, special(Special.SET_ZERO), c.config.can_id, timeout, time.perf_counter)
        except ArmError:
            raise ArmError(f"motor {c.describe()} did not answer the set-zero: its zero may not be set; {fix}, "
                           "then zero it again") from None
    return {"joint": joint, "can_id": motors[joint].can_id, "zeroed": True}


def plan(arm: Arm, config: RobotConfig, what: str, q_goal: np.ndarray | None = None,
         pose: tuple[float, ...] | None = None, joint: str | None = None, delta: float | None = None) -> Plan:
    """The move `what` ("home", "jog", "move") from the measured joints; the arm must be connected. ArmError
    for a goal outside the joint limits less GOAL_MARGIN_RAD or a tool outside the workspace box."""
    kin = arm.kin
    q0 = arm.state().q
    if what == "home":
        q_goal = np.array(config.q_ready)
    elif what == "jog":
        if joint not in arm.joint_names:
            raise ArmError(f"joint {joint!r} is not one of {', '.join(arm.joint_names)}")
        q_goal = q0.copy()
        q_goal[arm.joint_names.index(joint)] += float(delta)
    elif what == "move":
        q_goal = _pose_goal(arm, pose, q0)
    _check_goal(arm, what, q_goal, arm.limits)
    duration = joint_trajectory(q0, q_goal, config.motion_limits(arm.kin, BRINGUP_SPEED)).duration
    return Plan(what, q0, q_goal, duration, kin.fk(q0)[:3, 3], kin.fk(q_goal)[:3, 3])


def _pose_goal(arm: Arm, pose: tuple[float, ...], q0: np.ndarray) -> np.ndarray:
    """IK for tool pose (x, y, z m; roll, pitch, yaw deg, xyz Euler), seeded at q0, within the joint limits less
    GOAL_MARGIN_RAD; IKError with the fix."""
    x, y, z, roll, pitch, yaw = pose
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [roll, pitch, yaw], degrees=True).as_matrix()
    T[:3, 3] = x, y, z
    model = pin.Model(arm.kin.model)
    model.lowerPositionLimit = arm.limits.q_min + GOAL_MARGIN_RAD
    model.upperPositionLimit = arm.limits.q_max - GOAL_MARGIN_RAD
    kin = Kinematics(model, arm.kin.tool_frame)
    try:
        return kin.ik(T, q0)
    except IKError as exc:
        found = str(exc).split("; ")[0]  # what IK found, without its advice for a grasp
        raise IKError(f"move: {found}: the pose is out of the arm's reach or orientation range: give another --pose "
                      "(`deploy arm status` prints the current tool position and rpy)") from None


def _check_goal(arm: Arm, what: str, q_goal: np.ndarray, limits) -> None:
    """ArmError when a joint goal is outside its limits less GOAL_MARGIN_RAD or the tool leaves the workspace."""
    m = GOAL_MARGIN_RAD
    low, high = limits.q_min + m, limits.q_max - m
    bad = (q_goal < low) | (q_goal > high)
    if bad.any():
        j = int(np.argmax(bad))
        fix = {"home": "set q_ready inside it in the robot config", "jog": "choose a smaller --delta"}.get(
            what, "choose another goal")
        raise ArmError(f"{what}: joint {arm.joint_names[j]} goal {q_goal[j]:.3f} rad is outside its limits "
                       f"[{limits.q_min[j]:.3f}, {limits.q_max[j]:.3f}] less the {m} rad margin a move may "
                       f"overshoot by, [{low[j]:.3f}, {high[j]:.3f}]: {fix}")
    tool = arm.kin.fk(q_goal)[:3, 3]
    if np.any(tool < limits.workspace_min) or np.any(tool > limits.workspace_max):
        raise ArmError(f"{what}: the tool would end at {tool.round(3).tolist()} m, outside the workspace box "
                       f"{limits.workspace_min.tolist()} .. {limits.workspace_max.tolist()}: choose another goal")


def execute(arm: Arm, config: RobotConfig, p: Plan, hold_s: float = 0.0,
            progress: Callable[[float], None] | None = None) -> dict:
    """Run a planned move (the arm is connected), let it come to rest (SETTLE_S at most), hold `hold_s` s; the
    final joints and tool position. ArmError (the arm then stops) when a measured joint passes its limit or a
    joint ends farther than GOAL_TOLERANCE_RAD from its goal."""
    limits = config.motion_limits(arm.kin, BRINGUP_SPEED)

    def on_tick(state, t: float) -> None:
        _check_limits(arm, p, state.q)
        if progress is not None:
            progress(min(1.0, t / max(p.duration_s, 1e-9)))

    gap = np.abs(arm.state().q - p.q_start)
    if gap.max() > 0.02:
        j = int(np.argmax(gap))
        raise ArmError(f"{p.what}: joint {arm.joint_names[j]} moved {gap[j]:.3f} rad since the plan was made: run "
                       "the command again; if it moves again, it sags when enabled: check the gravity model "
                       "(gravity_compensation and the URDF's inertias) and the gains (kp, kd)")
    move_to_joints(arm, p.q_goal, limits, on_tick)
    for _ in range(int(np.ceil(SETTLE_S / arm.control_period_s))):
        state = arm.state()
        if np.abs(state.q - p.q_goal).max() <= GOAL_TOLERANCE_RAD and np.abs(state.dq).max() <= SETTLED_SPEED:
            break
        arm.sync()
        _check_limits(arm, p, arm.state().q)
    end = time.perf_counter() + hold_s
    while time.perf_counter() < end:
        arm.sync()
        _check_limits(arm, p, arm.state().q)
    q = arm.state().q
    _check_limits(arm, p, q)
    error = np.abs(q - p.q_goal)
    if error.max() > GOAL_TOLERANCE_RAD:
        j = int(np.argmax(error))
        raise ArmError(f"{p.what}: joint {arm.joint_names[j]} ended {error[j]:.3f} rad from its goal "
                       f"{p.q_goal[j]:.3f} (tolerance {GOAL_TOLERANCE_RAD} rad): the arm does not hold its goal; "
                       "check the gravity model (gravity_compensation and the URDF's inertias), the gains (kp, kd) "
                       "and any load on the arm")
    return {"q": q.round(4).tolist(), "tool_position_m": arm.kin.fk(q)[:3, 3].round(4).tolist(),
            "max_joint_error_rad": float(error.max())}


def _check_limits(arm: Arm, p: Plan, q: np.ndarray) -> None:
    """ArmError when a measured joint is past its limit (the arm's safety limits), farther than it was at the plan's
    start (a joint zeroed slightly outside may move back in)."""
    lim = arm.limits
    past = np.maximum(lim.q_min - q, q - lim.q_max)
    beyond = past - np.maximum(0.0, np.maximum(lim.q_min - p.q_start, p.q_start - lim.q_max))
    j = int(np.argmax(beyond))
    if beyond[j] > 0 and past[j] > 0:
        raise ArmError(f"{p.what}: joint {arm.joint_names[j]} measured {q[j]:.4f} rad, {past[j]:.4f} rad past its "
                       f"limits [{lim.q_min[j]:.3f}, {lim.q_max[j]:.3f}]: the joint overshoots; raise kd or lower "
                       "kp in the robot config")
