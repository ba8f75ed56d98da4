"""Every limit of the safety layer on both sides: each joint's position, velocity, acceleration (speeding up and
braking) and jump, each workspace axis's minimum and maximum, each joint's torque. First through the guard itself,
at the limit (allowed) and just past it (refused, naming the joint or the axis); then through motions that would
cross each limit, on the simulated arm (sim) and on the CAN driver over simulated motors (sim-can): the motion is
refused at the crossing, nothing past the limit is reached, and the arm ends stopped."""

import re

import numpy as np
import pybullet as pb
import pytest

from drivers.arm.damiao import MODELS, Feedback, Status
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import follow_cartesian_path, line_path, move_to_joints
from drivers.arm.motor_channels import MotorChannel, check_feedback
from drivers.arm.robot_config import MotorConfig, WatchdogConfig, load_robot_config
from drivers.arm.robots import panda
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.arm.trajectory import MotionLimits
from drivers.errors import ArmError
from sim_fallback.arm import SimArm
from sim_fallback.devices import sim_can_arm
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

KIN = Kinematics.panda()
LIMITS = SafetyLimits.for_robot(panda(), KIN)
GUARD = SafetyGuard(LIMITS, KIN.joint_names)
DT = 1.0 / 240
PAST = 1e-4  # just past a limit: 100x the guard's rounding slack (1e-6 relative)
TOOL = np.array([0.45, 0.0, 0.70])  # the tool at the ready pose, well inside the workspace box
JOINTS = range(len(KIN.joint_names))
SIDES = {"above": 1.0, "below": -1.0}
AXES = range(3)
PANDA_SIM = load_robot_config("panda_sim")
SCENARIO = Scenario.make("drawer", 0, "train")


def _check(q, dq=None, q_prev=None, dq_prev=None, tool=TOOL, q_measured=None, guard=GUARD):
    guard.check(q, dq, q if q_prev is None else q_prev, DT, tool, dq_prev, q_measured)


def _refused(pattern: str):
    return pytest.raises(ArmError, match="^safety stop: " + pattern)


def _name(joint: int) -> str:
    return re.escape(KIN.joint_names[joint])


# --- the guard itself ---------------------------------------------------------------------------------------


def test_the_arm_configs_limits_are_the_robots():
    config = PANDA_SIM.safety_limits(PANDA_SIM.kinematics())
    for name in ("q_min", "q_max", "v_max", "a_max", "workspace_min", "workspace_max"):
        np.testing.assert_array_equal(getattr(config, name), getattr(LIMITS, name), err_msg=name)


@pytest.mark.parametrize("side", SIDES)
@pytest.mark.parametrize("joint", JOINTS)
def test_position_limit_of_every_joint_on_both_sides(joint, side):
    limit = (LIMITS.q_max if side == "above" else LIMITS.q_min)[joint]
    q = panda().q_ready.copy()
    q[joint] = limit
    _check(q)
    q[joint] = limit + SIDES[side] * PAST
    with _refused(rf"joint {_name(joint)} position {q[joint]:.4f} rad is {side} its limit {limit:.4f}: re-plan"):
        _check(q)


def test_of_several_joints_past_their_limits_the_farthest_is_named():
    q = panda().q_ready.copy()
    q[1], q[5] = LIMITS.q_max[1] + 0.01, LIMITS.q_max[5] + 0.02
    with _refused("joint panda_joint6 position"):
        _check(q)
    dq = np.zeros(7)
    dq[0], dq[4] = -1.01 * LIMITS.v_max[0], 1.02 * LIMITS.v_max[4]
    with _refused("joint panda_joint5 velocity"):
        _check(panda().q_ready, dq, dq_prev=dq)


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("joint", JOINTS)
def test_velocity_limit_of_every_joint_in_both_directions(joint, sign):
    q, dq = panda().q_ready, np.zeros(7)
    dq[joint] = sign * LIMITS.v_max[joint]
    _check(q, dq, dq_prev=dq)
    dq[joint] *= 1 + PAST
    with _refused(rf"joint {_name(joint)} velocity {dq[joint]:.3f} rad/s exceeds its limit "
                  rf"{LIMITS.v_max[joint]:.3f}: lower"):
        _check(q, dq, dq_prev=dq)


@pytest.mark.parametrize(("v_start", "sign"), [(0.0, 1.0), (0.0, -1.0), (0.5, -1.0), (-0.5, 1.0)],
                         ids=["speeding-up-positive", "speeding-up-negative", "braking-positive", "braking-negative"])
@pytest.mark.parametrize("joint", JOINTS)
def test_acceleration_limit_of_every_joint_speeding_up_and_braking(joint, v_start, sign):
    q, dq_prev = panda().q_ready, np.zeros(7)
    dq_prev[joint] = v_start * LIMITS.v_max[joint]
    dq = dq_prev.copy()
    dq[joint] += sign * LIMITS.a_max[joint] * DT
    _check(q, dq, dq_prev=dq_prev)
    dq[joint] = dq_prev[joint] + sign * LIMITS.a_max[joint] * (1 + PAST) * DT
    a = (dq[joint] - dq_prev[joint]) / DT
    with _refused(rf"joint {_name(joint)} acceleration {a:.2f} rad/s\^2 exceeds its limit {LIMITS.a_max[joint]:.2f}"):
        _check(q, dq, dq_prev=dq_prev)


def test_acceleration_is_not_checked_without_a_previous_velocity():
    dq = np.zeros(7)
    dq[0] = LIMITS.v_max[0]  # from rest in one cycle: the stream's first command has nothing to compare with
    _check(panda().q_ready, dq)


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("joint", JOINTS)
def test_jump_limit_of_every_joint_in_both_directions(joint, sign):
    q_prev = panda().q_ready
    q = q_prev.copy()
    max_step = LIMITS.v_max[joint] * DT + LIMITS.jump_tolerance_rad
    q[joint] += sign * max_step
    _check(q, q_prev=q_prev)
    q[joint] = q_prev[joint] + sign * (max_step + PAST)
    with _refused(rf"joint {_name(joint)} command jumps {sign * (max_step + PAST):.4f} rad in one "
                  rf"{DT * 1e3:.1f} ms cycle \(limit {max_step:.4f} rad\)"):
        _check(q, q_prev=q_prev)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_step_is_measured_from_the_nearer_of_the_last_command_and_the_arm(sign):
    q_prev = panda().q_ready
    measured = q_prev.copy()
    measured[4] += sign * 0.03  # a held door pushed the compliant arm off its last command
    near_arm = measured.copy()
    near_arm[4] += sign * 0.005
    _check(near_arm, q_prev=q_prev, q_measured=measured)
    with _refused("joint panda_joint5 command jumps"):
        _check(near_arm, q_prev=q_prev)  # without the measurement it is a 3.5 cm jump
    behind = q_prev.copy()
    behind[4] -= sign * 0.03  # away from the arm and from the last command
    with _refused(rf"joint panda_joint5 command jumps {-sign * 0.03:.4f} rad"):
        _check(behind, q_prev=q_prev, q_measured=measured)


@pytest.mark.parametrize("side", ["max", "min"])
@pytest.mark.parametrize("axis", AXES)
def test_workspace_box_on_both_sides_of_every_axis(axis, side):
    bound = (LIMITS.workspace_max if side == "max" else LIMITS.workspace_min)[axis]
    tool = TOOL.copy()
    tool[axis] = bound
    _check(panda().q_ready, tool=tool)
    tool[axis] = bound + (PAST if side == "max" else -PAST)
    with _refused(rf"tool position \({tool[0]:.3f}, {tool[1]:.3f}, {tool[2]:.3f}\) m leaves the workspace box "
                  rf".* along {'xyz'[axis]}: re-plan inside it"):
        _check(panda().q_ready, tool=tool)


@pytest.mark.parametrize("axis", AXES)
def test_a_non_finite_tool_position_is_outside_the_box(axis):
    tool = TOOL.copy()
    tool[axis] = np.nan
    with _refused(rf"tool position .* along {'xyz'[axis]}"):
        _check(panda().q_ready, tool=tool)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("what", ["position", "velocity", "previous position", "previous velocity",
                                  "measured position"])
def test_every_non_finite_input_is_refused_naming_it(what, value):
    q, dq = panda().q_ready.copy(), np.zeros(7)
    inputs = {"position": q.copy(), "velocity": dq.copy(), "previous position": q.copy(),
              "previous velocity": dq.copy(), "measured position": q.copy()}
    inputs[what][2] = value
    with _refused(f"joint panda_joint3 {what} command is not finite: a planner or IK bug produced NaN"):
        GUARD.check(inputs["position"], inputs["velocity"], inputs["previous position"], DT, TOOL,
                    inputs["previous velocity"], inputs["measured position"])


@pytest.mark.parametrize("dt", [0.0, -DT, np.nan, np.inf])
def test_a_control_period_that_is_not_a_positive_time_is_refused(dt):
    with _refused("control period"):
        GUARD.check(panda().q_ready, np.zeros(7), panda().q_ready, dt, TOOL, np.zeros(7))


@pytest.mark.parametrize(("field", "value", "what"), [
    ("q_max", "nan", "q_min must be below q_max"), ("q_min", "q_max", "q_min must be below q_max"),
    ("v_max", "nan", "v_max and a_max must be above 0"), ("a_max", "zero", "v_max and a_max must be above 0"),
    ("workspace_max", "nan", "workspace_min must be below workspace_max"),
    ("workspace_min", "workspace_max", "workspace_min must be below workspace_max"),
    ("v_max", "short", "one value per joint"),
])
def test_limits_that_cannot_hold_are_refused(field, value, what):
    fields = {name: getattr(LIMITS, name).copy() for name in
              ("q_min", "q_max", "v_max", "a_max", "workspace_min", "workspace_max")}
    new = {"nan": np.full_like(fields[field], np.nan), "zero": np.zeros_like(fields[field]),
           "short": fields[field][:-1]}.get(value)
    fields[field] = fields[value].copy() if new is None else new
    with pytest.raises(ArmError, match=f"invalid safety limits: {what}"):
        SafetyLimits(**fields)


def test_a_robot_configs_narrower_limits_hold_on_both_sides():
    joints = [j.model_copy(update={"q_min": -1.0, "q_max": 0.5, "v_max": 1.0}) if j.name == "panda_joint1" else j
              for j in PANDA_SIM.joints]
    limits = PANDA_SIM.model_copy(update={"joints": joints}).safety_limits(KIN)
    guard = SafetyGuard(limits, KIN.joint_names)
    q, dq = panda().q_ready.copy(), np.zeros(7)
    for value, side in ((0.5 + PAST, "above"), (-1.0 - PAST, "below")):
        q[0] = value
        with _refused(f"joint panda_joint1 position .* is {side} its limit"):
            _check(q, guard=guard)
    q[0], dq[0] = 0.0, -1.0 - PAST
    with _refused("joint panda_joint1 velocity -1.000 rad/s exceeds its limit 1.000"):
        _check(q, dq, dq_prev=dq, guard=guard)


def _channel(tau: float, status: Status = Status.ENABLED) -> MotorChannel:
    c = MotorChannel("panda_joint1", MotorConfig(can_id=1, master_id=0x11), MODELS["DM4340"])
    c.feedback = Feedback(1, status, 0.0, 0.0, tau, 30, 32)
    return c


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_measured_torque_limit_on_both_sides(sign):
    watchdog = WatchdogConfig()
    limit = 12.0 * watchdog.torque_margin
    check_feedback(_channel(sign * limit), 0.0, watchdog, tau_max=12.0)
    with _refused(rf"joint panda_joint1 \(CAN id 1, master 0x11\) torque {limit + 0.01:.1f} N m exceeds "
                  rf"{limit:.1f} N m \(tau_max x torque_margin\): motors disabled"):
        check_feedback(_channel(sign * (limit + 0.01)), 0.0, watchdog, tau_max=12.0)
    check_feedback(_channel(sign * 10 * limit), 0.0, watchdog, tau_max=None)  # the gripper has no torque limit


def test_feedback_age_limit_on_both_sides():
    watchdog = WatchdogConfig()
    timeout = watchdog.feedback_timeout_s
    check_feedback(_channel(0.0), timeout, watchdog, tau_max=12.0)
    with pytest.raises(ArmError, match=rf"^watchdog: joint panda_joint1 .* no valid feedback for "
                                       rf"{(timeout + 1e-3) * 1e3:.0f} ms \(limit {timeout * 1e3:.0f} ms"):
        check_feedback(_channel(0.0), timeout + 1e-3, watchdog, tau_max=12.0)


@pytest.mark.parametrize("status", list(Status), ids=lambda s: s.name.lower())
def test_every_motor_status_but_enabled_stops_the_arm(status):
    c = _channel(0.0, status)
    if status is Status.ENABLED:
        check_feedback(c, 0.0, WatchdogConfig(), tau_max=12.0)
        return
    words = "disabled itself" if status is Status.DISABLED else status.name.lower().replace("_", "-")
    for tau_max in (12.0, None):  # a joint's motor and the gripper's
        with pytest.raises(ArmError, match=f"^joint panda_joint1 .*{words}"):
            check_feedback(c, 0.0, WatchdogConfig(), tau_max=tau_max)


# --- motions that would cross a limit, on sim and sim-can -------------------------------------------------------


class Bench:
    """A simulated world and its Panda as arm `kind` ("sim" or "sim-can"); the truth is read from PyBullet."""

    def __init__(self, kind: str, start: dict[int, float] | None = None, guard: SafetyGuard | None = None) -> None:
        self.world = SimWorld(SCENARIO)
        names = self.world.robot_spec.arm_joints
        self._joints = [self.world.robot_joints[n] for n in names]
        for joint, value in (start or {}).items():
            pb.resetJointState(self.world.robot_id, self._joints[joint], value, physicsClientId=self.world.client)
        self.motors = None
        if kind == "sim":
            self.arm = SimArm(self.world, guard=guard)
        else:
            self.arm, self.motors = sim_can_arm(PANDA_SIM, self.world)
            self.arm.connect()
            self.arm.guard = guard or self.arm.guard

    def q(self) -> np.ndarray:
        """The joints' true positions."""
        states = pb.getJointStates(self.world.robot_id, self._joints, physicsClientId=self.world.client)
        return np.array([s[0] for s in states])

    def assert_stopped(self) -> np.ndarray:
        """At rest a second after the stop (an arm stopped at speed overshoots and rings first) and still for
        half a second more; on sim-can every motor disabled and commands refused. The joints at rest."""
        if self.motors is not None:
            assert not any(m.enabled for m in self.motors.motors)
            with pytest.raises(ArmError, match="not enabled"):
                self.arm.command(self.q())
        self.world.clock.step(240)
        q0 = self.q()
        self.world.clock.step(120)
        assert np.abs(self.q() - q0).max() < 2e-3
        return q0

    def close(self) -> None:
        self.arm.disconnect()
        self.world.close()


@pytest.fixture(params=["sim", "sim-can"])
def bench(request):
    opened = []

    def make(**kwargs) -> Bench:
        opened.append(Bench(request.param, **kwargs))
        return opened[-1]

    yield make
    for b in opened:
        b.close()


J7 = 6  # the wrist: turning it moves no other joint and keeps the tool point where it is
SLOW = MotionLimits(0.5, 5.0, 500.0)


@pytest.mark.parametrize("side", SIDES)
def test_a_move_past_a_joint_limit_stops_at_the_limit(bench, side):
    sign = SIDES[side]
    limit = (LIMITS.q_max if side == "above" else LIMITS.q_min)[J7]
    b = bench(start={J7: limit - sign * 0.05})
    goal = b.q()
    goal[J7] = limit + sign * 0.05
    with _refused(rf"joint panda_joint7 position .* rad is {side} its limit {limit:.4f}"):
        move_to_joints(b.arm, goal, SLOW)
    rest = b.assert_stopped()[J7]
    assert -0.02 < sign * (rest - limit) < 5e-3  # stopped at the crossing, not past it by more than the braking


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_move_faster_than_a_joint_may_turn_is_refused(bench, sign):
    b = bench()
    v = np.full(7, 0.1)
    v[J7] = 1.2 * LIMITS.v_max[J7]
    goal = b.q()
    goal[J7] += sign * 1.5
    with _refused(rf"joint panda_joint7 velocity {'-' if sign < 0 else ''}2\.6\d\d rad/s exceeds its limit 2.610"):
        move_to_joints(b.arm, goal, MotionLimits(v, 15.0, 5000.0))
    b.assert_stopped()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_move_that_speeds_up_too_hard_is_refused(bench, sign):
    b = bench()
    a = np.full(7, 1.0)
    a[J7] = 1.5 * LIMITS.a_max[J7]
    goal = b.q()
    goal[J7] += sign * 0.5
    with _refused(rf"joint panda_joint7 acceleration {'-' if sign < 0 else ''}\d+\.\d\d rad/s\^2 exceeds its limit "
                  "20.00"):
        move_to_joints(b.arm, goal, MotionLimits(2.0, a, 1e5))
    b.assert_stopped()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_motion_that_brakes_too_hard_is_refused(bench, sign):
    """Speed up within the limit to 1 rad/s, then command standstill in one cycle (-240 rad/s^2 against 20)."""
    b = bench()
    arm, dt = b.arm, b.arm.control_period_s
    q, dq = b.q(), np.zeros(7)
    while abs(dq[J7]) < 1.0:
        dq[J7] += sign * 0.5 * LIMITS.a_max[J7] * dt
        q = q + dq * dt
        arm.command(q, dq.copy())
        arm.sync()
    with _refused(rf"joint panda_joint7 acceleration {-sign * abs(dq[J7]) / dt:.2f} rad/s\^2 exceeds its limit 20.00"):
        arm.command(q, np.zeros(7))
    b.assert_stopped()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_command_that_jumps_is_refused(bench, sign):
    b = bench()
    q = b.q()
    q[J7] += sign * 0.05
    with _refused(rf"joint panda_joint7 command jumps {sign * 0.05:.4f} rad"):
        b.arm.command(q)
    b.assert_stopped()


@pytest.mark.parametrize("side", ["max", "min"])
@pytest.mark.parametrize("axis", AXES)
def test_a_line_out_of_the_workspace_box_stops_inside_it(bench, axis, side):
    """A box 3 cm around the start on every axis, a 6 cm line out of it through each face."""
    p0 = KIN.fk(SCENARIO.q_start)[:3, 3]
    box = SafetyLimits(LIMITS.q_min, LIMITS.q_max, LIMITS.v_max, LIMITS.a_max, p0 - 0.03, p0 + 0.03)
    b = bench(guard=SafetyGuard(box, KIN.joint_names))
    direction = np.zeros(3)
    direction[axis] = 1.0 if side == "max" else -1.0
    with _refused(rf"tool position .* leaves the workspace box .* along {'xyz'[axis]}"):
        follow_cartesian_path(b.arm, KIN, line_path(KIN.fk(b.q()), direction), 0.06, MotionLimits(0.1, 0.5, 5.0))
    p = KIN.fk(b.assert_stopped())[:3, 3]
    assert np.all(p > box.workspace_min - 1e-3) and np.all(p < box.workspace_max + 1e-3)
    assert abs(p[axis] - p0[axis]) > 0.02  # it moved up to the face


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_torque_above_the_limit_in_either_direction_stops_the_can_arm(sign):
    """sim-can only: the simulated arm (sim) has no torque check, PyBullet caps each joint at its URDF effort."""
    joints = [j.model_copy(update={"tau_max": 0.05}) if j.name == "panda_joint1" else j for j in PANDA_SIM.joints]
    config = PANDA_SIM.model_copy(update={"joints": joints, "control_rate_hz": 500.0})
    arm, motors = sim_can_arm(config)
    with arm:
        q0 = arm.state().q
        with pytest.raises(ArmError, match=r"^safety stop: joint panda_joint1 .*torque \d+\.\d N m exceeds 0\.1 N m"):
            move_to_joints(arm, q0 + np.r_[sign * 0.5, np.zeros(6)], MotionLimits(0.5, 2.0, 20.0))
        assert sign * motors.motor("panda_joint1").tau > 0.06  # the torque that tripped pushed the way it was sent
        assert not any(m.enabled for m in motors.motors)
