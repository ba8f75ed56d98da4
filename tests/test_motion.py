"""Motion code on the ideal arm: joint moves, Cartesian lines and arcs, stopping, blocking, safety, and door
arcs / drawer lines from the ready pose that stay clear of joint limits without drifting."""

import numpy as np
import pinocchio as pin
import pytest

from drivers.arm.base import ArmState
from drivers.arm.ideal import IdealArm
from drivers.arm.motion import (
    arc_path,
    follow_cartesian_path,
    follow_joint_trajectory,
    line_path,
    move_to_joints,
    move_to_pose,
)
from drivers.arm.robot_config import panda_sim_config
from drivers.arm.robots import panda
from drivers.arm.trajectory import MotionLimits, joint_trajectory
from drivers.errors import ArmError

LINE_LIMITS = MotionLimits(0.1, 0.5, 5.0)  # m/s, m/s^2, m/s^3
ARC_LIMITS = MotionLimits(0.4, 1.0, 10.0)  # rad/s, rad/s^2, rad/s^3
DRAWER_LIMITS, DOOR_LIMITS = MotionLimits(0.1, 0.3, 3.0), MotionLimits(0.25, 0.6, 6.0)  # opening speeds
LIMIT_MARGIN_RAD = 0.05
# 0.4 rad from the ready pose, where the tool Jacobian loses rank (see test_kinematics.py).
Q_SINGULAR = np.array([-0.446, -0.787, 0.443, -2.363, np.pi / 2, 3.346, -0.66])


class EndStopArm(IdealArm):
    """An ideal arm holding a drawer that hits its end stop: the tool cannot go below x = x_stop."""

    def __init__(self, x_stop: float) -> None:
        arm = IdealArm.panda()
        super().__init__(arm.kin, arm.guard, panda().q_ready)
        self.x_stop = x_stop

    def sync(self) -> None:
        q_before = self._q
        super().sync()
        if self.kin.fk(self._q)[0, 3] < self.x_stop:
            self._q, self._dq = q_before, np.zeros_like(q_before)


def _record(states: list[ArmState]):
    def on_tick(state: ArmState, t: float) -> bool:
        states.append(state)
        return True

    return on_tick


def _rotation_error(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.linalg.norm(pin.log3(R_a.T @ R_b)))


def test_line_keeps_the_tool_on_the_line():
    arm = IdealArm.panda()
    kin = arm.kin
    T0 = kin.fk(arm.state().q)
    u = np.array([-1.0, 0.0, 0.0])
    states: list[ArmState] = []
    result = follow_cartesian_path(arm, kin, line_path(T0, u), 0.2, LINE_LIMITS, on_tick=_record(states))
    assert result.reason == "completed" and not result.stopped_early
    assert result.s_reached == pytest.approx(0.2)
    assert np.allclose(np.diff([s.t for s in states]), arm.control_period_s)  # on_tick at every tick
    for state in states:
        T = kin.fk(state.q)
        offset = T[:3, 3] - T0[:3, 3]
        along = offset @ u
        assert -1e-6 <= along <= 0.2 + 1e-6
        assert np.linalg.norm(offset - along * u) < 1e-3
        assert _rotation_error(T[:3, :3], T0[:3, :3]) < 1e-3
    assert np.allclose(kin.fk(arm.state().q)[:3, 3], T0[:3, 3] + 0.2 * u, atol=1e-5)
    assert np.allclose(arm.state().dq, 0.0, atol=1e-5)
    assert len(result.t) == len(result.s) == len(result.planned) == len(result.measured)
    assert len(result.t) == pytest.approx(len(states) / 10, abs=1.5)
    assert result.t[-1] == pytest.approx(states[-1].t) and result.max_tracking_error_m < 1e-4


def test_arc_turns_the_tool_with_the_door():
    arm = IdealArm.panda()
    kin = arm.kin
    T0 = kin.fk(arm.state().q)
    hinge, up = T0[:3, 3] + [0.0, -0.4, 0.0], np.array([0.0, 0.0, 1.0])
    angle = np.radians(60)
    states: list[ArmState] = []
    path = arc_path(T0, hinge, up)
    result = follow_cartesian_path(arm, kin, path, angle, ARC_LIMITS, on_tick=_record(states))
    assert result.reason == "completed" and result.s_reached == pytest.approx(angle)
    for state in states:
        T = kin.fk(state.q)
        radial = T[:3, 3] - hinge
        assert abs(np.linalg.norm(radial[:2]) - 0.4) < 1e-3 and abs(radial[2]) < 1e-3
        turned = np.arctan2(radial[1], radial[0]) - np.pi / 2  # the handle starts at +y from the hinge
        assert _rotation_error(T[:3, :3], pin.exp3(turned * up) @ T0[:3, :3]) < 1e-3
    T_end = kin.fk(arm.state().q)
    assert np.allclose(T_end[:3, 3], hinge + 0.4 * np.array([-np.sin(angle), np.cos(angle), 0.0]), atol=1e-4)
    assert np.allclose(T_end[:3, 2], [np.cos(angle), np.sin(angle), 0.0], atol=1e-4)  # approach axis turned


def test_an_arc_that_does_not_turn_the_tool_keeps_its_orientation():
    T0 = np.eye(4)
    T0[:3, 3] = [0.6, 0.0, 0.5]
    hinge, up = T0[:3, 3] + [0.0, -0.4, 0.0], np.array([0.0, 0.0, 1.0])
    angle = np.radians(45)
    T = arc_path(T0, hinge, up, turn=False)(angle)
    assert np.allclose(T[:3, :3], T0[:3, :3])
    assert np.allclose(T[:3, 3], arc_path(T0, hinge, up)(angle)[:3, 3])  # the same path


def test_on_tick_false_brakes_along_the_path():
    arm = IdealArm.panda()
    kin = arm.kin
    T0 = kin.fk(arm.state().q)
    s_at_stop = []

    def stop_after_half_a_second(state: ArmState, t: float) -> bool:
        if t >= 0.5 and not s_at_stop:
            s_at_stop.append(-(kin.fk(state.q)[0, 3] - T0[0, 3]))
        return t < 0.5

    result = follow_cartesian_path(
        arm, kin, line_path(T0, [-1, 0, 0]), 0.2, LINE_LIMITS, on_tick=stop_after_half_a_second
    )
    assert result.stopped_early and result.reason == "stopped by on_tick"
    assert s_at_stop[0] < result.s_reached < 0.2
    assert result.t[-1] < 1.0
    assert np.allclose(arm.state().dq, 0.0, atol=1e-6)
    travelled = -(kin.fk(arm.state().q)[0, 3] - T0[0, 3])
    assert travelled == pytest.approx(result.s_reached, abs=1e-5)


def test_a_blocked_arm_stops_with_reason_blocked():
    arm = EndStopArm(x_stop=panda_tool_x() - 0.05)
    T0 = arm.kin.fk(arm.state().q)
    result = follow_cartesian_path(arm, arm.kin, line_path(T0, [-1, 0, 0]), 0.2, LINE_LIMITS)
    assert result.stopped_early and result.reason.startswith("blocked: tracking error")
    assert 0.02 < result.max_tracking_error_m < 0.04  # 20 mm, then braking pushes on about 15 mm
    assert result.s_reached < 0.1
    measured_x = result.measured[:, 0, 3]
    assert measured_x.min() >= T0[0, 3] - 0.05 - 1e-3


def panda_tool_x() -> float:
    arm = IdealArm.panda()
    return float(arm.kin.fk(arm.state().q)[0, 3])


def test_unsolvable_paths_raise_before_any_motion():
    arm = IdealArm.panda()
    kin = arm.kin
    T0 = kin.fk(arm.state().q)
    q0 = arm.state().q
    lost = r"^ik: lost the Cartesian path at s = 0\.\d+ of 1\.0000: the tool pose"
    with pytest.raises(ArmError, match=lost):
        follow_cartesian_path(arm, kin, line_path(T0, [1, 0, 0]), 1.0, LINE_LIMITS)
    assert arm.state().t == 0.0 and np.array_equal(arm.state().q, q0)
    with pytest.raises(ArmError, match=r"^ik: .* needs joint panda_joint\d at its velocity limit"):  # even slowed
        follow_cartesian_path(arm, kin, line_path(T0, [0, 0, -1]), 0.3, MotionLimits(100.0, 1000.0, 10000.0))
    assert arm.state().t == 0.0 and np.array_equal(arm.state().q, q0)
    far = T0.copy()
    far[2, 3] += 0.05
    with pytest.raises(ArmError, match="path starts 50 mm from the tool"):
        follow_cartesian_path(arm, kin, line_path(far, [0, 0, -1]), 0.1, LINE_LIMITS)
    with pytest.raises(ValueError, match="line direction"):
        line_path(T0, [0, 0, 0])


def test_zero_length_path_does_not_move():
    arm = IdealArm.panda()
    T0 = arm.kin.fk(arm.state().q)
    result = follow_cartesian_path(arm, arm.kin, line_path(T0, [0, 0, 1]), 0.0, LINE_LIMITS)
    assert result.reason == "completed" and result.s_reached == 0.0 and arm.state().t == 0.0


def test_move_to_joints_and_to_pose_reach_their_goals():
    arm = IdealArm.panda()
    kin = arm.kin
    limits = panda_sim_config().motion_limits(kin, 0.5)
    q_goal = panda().q_ready + np.array([0.3, 0.2, -0.2, 0.3, 0.2, -0.3, 0.5])
    ticks = []
    assert move_to_joints(arm, q_goal, limits, on_tick=lambda state, t: ticks.append(t) is None)
    assert np.allclose(arm.state().q, q_goal) and len(ticks) > 10
    T_goal = kin.fk(panda().q_ready)
    T_goal[:3, 3] += [0.1, 0.1, -0.1]
    assert move_to_pose(arm, kin, T_goal, limits)
    T = kin.fk(arm.state().q)
    assert np.allclose(T[:3, 3], T_goal[:3, 3], atol=1e-4)
    assert _rotation_error(T[:3, :3], T_goal[:3, :3]) < 1e-3


def test_joint_trajectory_stopped_by_on_tick_ends_at_rest_short_of_the_goal():
    arm = IdealArm.panda()
    limits = panda_sim_config().motion_limits(arm.kin, 0.5)
    q_goal = panda().q_ready + 0.5
    traj = joint_trajectory(arm.state().q, q_goal, limits)
    assert not follow_joint_trajectory(arm, traj, on_tick=lambda state, t: t < traj.duration / 2)
    assert np.allclose(arm.state().dq, 0.0, atol=1e-9)
    assert not np.allclose(arm.state().q, q_goal, atol=0.05)
    assert arm.state().t < traj.duration


def test_safety_violation_stops_the_arm():
    arm = IdealArm.panda()
    too_fast = MotionLimits(arm.kin.v_max * 2.0, 7.0, 100.0)  # accelerations within the safety limits
    with pytest.raises(ArmError, match="joint panda_joint1 velocity .* exceeds its limit"):
        move_to_joints(arm, panda().q_ready + [1.5, 0, 0, 0, 0, 0, 0], too_fast)
    assert 0.0 < arm.state().t and np.allclose(arm.state().dq, 0.0)
    arm.sync()
    assert np.allclose(arm.state().dq, 0.0)  # holding, not moving on


def test_an_on_tick_exception_stops_the_arm():
    arm = IdealArm.panda()
    limits = panda_sim_config().motion_limits(arm.kin, 0.5)

    def camera_fails(state: ArmState, t: float) -> bool:
        if t > 0.2:
            raise RuntimeError("camera unplugged")
        return True

    with pytest.raises(RuntimeError, match="camera unplugged"):
        move_to_joints(arm, panda().q_ready + 0.5, limits, on_tick=camera_fails)
    q = arm.state().q
    arm.sync()
    assert np.array_equal(arm.state().q, q)


def test_ideal_gripper_moves_to_its_command():
    arm = IdealArm.panda()
    arm.set_gripper(0.0)
    for _ in range(500):  # 1 s at 0.1 m/s covers the 0.08 m stroke
        arm.sync()
    assert arm.state().gripper_width_m == pytest.approx(0.0, abs=1e-12)
    arm.set_gripper(1.0)  # clamped to the stroke
    arm.sync()
    assert arm.state().gripper_width_m == pytest.approx(0.1 * arm.control_period_s)
    with pytest.raises(ArmError, match="not finite"):
        arm.set_gripper(float("nan"))


def _follow(arm: IdealArm, path, length: float, limits: MotionLimits, **kwargs) -> tuple:
    """follow_cartesian_path recording every tick: (result, joint positions (N, 7), joint velocities)."""
    states: list[ArmState] = []
    result = follow_cartesian_path(arm, arm.kin, path, length, limits, on_tick=_record(states), **kwargs)
    return result, np.array([s.q for s in states]), np.array([s.dq for s in states])


def _assert_clear_of_limits(arm: IdealArm, qs: np.ndarray, dqs: np.ndarray) -> None:
    kin = arm.kin
    assert np.all(np.abs(dqs) <= kin.v_max)
    assert np.all(qs > kin.q_min + LIMIT_MARGIN_RAD) and np.all(qs < kin.q_max - LIMIT_MARGIN_RAD)


def _assert_joints_1_and_3_bounded(qs: np.ndarray, q_rest: np.ndarray) -> None:
    """Joints 1 and 3 turn with the task (up to ~1.7 rad for a quarter door) but never spin."""
    for j in (0, 2):
        assert np.abs(qs[:, j] - q_rest[j]).max() < 2.0
        assert np.abs(np.diff(qs[:, j])).sum() < 2.5  # total travel


@pytest.mark.parametrize(
    ("hinge_y", "degrees"), [(0.3, 90), (0.4, 90), (-0.3, 90), (-0.4, 90), (0.5, 70), (-0.5, 70)]
)
def test_door_arcs_from_the_ready_pose_stay_clear_of_the_limits(hinge_y, degrees):
    arm = IdealArm.panda()
    T0 = arm.kin.fk(arm.state().q)
    hinge, up = T0[:3, 3] + [0.0, hinge_y, 0.0], np.array([0.0, 0.0, 1.0])
    angle = -np.sign(hinge_y) * np.radians(degrees)  # the handle swings toward the robot
    result, qs, dqs = _follow(arm, arc_path(T0, hinge, np.sign(angle) * up), abs(angle), DOOR_LIMITS)
    assert result.reason == "completed" and result.s_reached == pytest.approx(abs(angle))
    _assert_clear_of_limits(arm, qs, dqs)
    _assert_joints_1_and_3_bounded(qs, panda().q_ready)
    T_end = arm.kin.fk(arm.state().q)
    R = pin.exp3(angle * up)
    assert np.allclose(T_end[:3, 3], hinge + R @ (T0[:3, 3] - hinge), atol=1e-5)
    assert _rotation_error(T_end[:3, :3], R @ T0[:3, :3]) < 1e-4


@pytest.mark.parametrize(
    ("direction", "length"), [((-1, 1, 0), 0.45), ((-1, -1, 0), 0.45), ((-1, 0, 0), 0.25)]
)
def test_drawer_lines_from_the_ready_pose_stay_clear_of_the_limits(direction, length):
    arm = IdealArm.panda()
    T0 = arm.kin.fk(arm.state().q)
    result, qs, dqs = _follow(arm, line_path(T0, direction), length, DRAWER_LIMITS)
    assert result.reason == "completed"
    _assert_clear_of_limits(arm, qs, dqs)
    _assert_joints_1_and_3_bounded(qs, panda().q_ready)
    u = np.array(direction) / np.linalg.norm(direction)
    assert np.allclose(arm.kin.fk(arm.state().q)[:3, 3], T0[:3, 3] + length * u, atol=1e-5)


def test_closed_loops_bring_the_arm_back_to_its_posture():
    arm = IdealArm.panda()
    q0 = arm.state().q
    T0 = arm.kin.fk(q0)

    def circle(s: float) -> np.ndarray:  # 0.1 m radius in the x-z plane, back at the start every 2 pi
        T = T0.copy()
        T[[0, 2], 3] += 0.1 * np.array([np.cos(s) - 1.0, np.sin(s)])
        return T

    for _ in range(3):
        result, qs, dqs = _follow(arm, circle, 2 * np.pi, MotionLimits(1.5, 3.0, 30.0))
        assert result.reason == "completed"
        _assert_clear_of_limits(arm, qs, dqs)
    assert np.abs(arm.state().q - q0).max() < 0.05  # least squares alone drifts ~0.25 rad per loop


def test_paths_near_a_singularity_pass_or_stop_before_moving():
    arm = IdealArm.panda()
    kin = arm.kin
    M0, M1 = pin.SE3(kin.fk(arm.state().q)), pin.SE3(kin.fk(Q_SINGULAR))
    twist = pin.log6(M0.actInv(M1))

    def through_the_singularity(s: float) -> np.ndarray:  # the singular pose at s = 1, then as far again
        return (M0 * pin.exp6(s * twist)).homogeneous

    result, qs, dqs = _follow(arm, through_the_singularity, 2.0, MotionLimits(0.5, 1.0, 10.0))
    assert result.reason == "completed" and np.all(np.isfinite(qs))
    _assert_clear_of_limits(arm, qs, dqs)

    arm = IdealArm.panda(Q_SINGULAR)
    U = np.linalg.svd(kin.jacobian(Q_SINGULAR))[0]
    lost = U[:3, -1] / np.linalg.norm(U[:3, -1])  # the tool direction the arm cannot move in
    with pytest.raises(ArmError, match=r"^ik: lost the Cartesian path at s = 0\.0000 of 0\.1000"):
        follow_cartesian_path(arm, kin, line_path(kin.fk(Q_SINGULAR), lost), 0.1, LINE_LIMITS)
    assert arm.state().t == 0.0 and np.array_equal(arm.state().q, Q_SINGULAR)  # never moved


def _plan_accelerations(qs: np.ndarray, q0: np.ndarray, dt: float) -> np.ndarray:
    velocity = np.diff(np.vstack([q0, q0, qs]), axis=0) / dt
    return np.abs(np.diff(velocity, axis=0)) / dt


def test_a_cartesian_plan_whose_joints_would_accelerate_past_the_limits_is_slowed_down():
    from drivers.arm.motion import ACCELERATION_SHARE, POSTURE_GAIN_PER_S, Tracker, _plan_within_acceleration
    from drivers.arm.trajectory import PathProfile

    arm = IdealArm.panda()
    kin, q0, dt = arm.kin, arm.state().q, arm.control_period_s
    T0 = kin.fk(q0)
    path = line_path(T0, [0.0, 0.0, -1.0])
    profile = PathProfile(0.1, 0.2, 2.0, 20.0)
    track = Tracker(kin, path, 0.1, q0, kin.v_max * dt, POSTURE_GAIN_PER_S * dt, 0.2 * dt)
    _, qs = track.plan(profile, dt, q0)
    needed = _plan_accelerations(qs, q0, dt).max(axis=0)
    a_max = np.maximum(needed / 2.0, 1e-3)  # the full-speed plan needs twice what this arm may do
    slowed, s, qs = _plan_within_acceleration(track, profile, dt, q0, a_max)
    assert slowed.duration > profile.duration and s[-1] == pytest.approx(0.1)
    assert np.all(_plan_accelerations(qs, q0, dt) <= ACCELERATION_SHARE * a_max + 1e-9)
    with pytest.raises(ArmError, match=r"^ik: the path needs joint panda_joint\d to accelerate at"):
        _plan_within_acceleration(track, profile, dt, q0, needed / 1000.0)


def test_a_cartesian_plan_that_needs_a_joint_past_its_speed_limit_is_slowed_down():
    """A door's arc from a configuration with joint 2 near zero (joints 1 and 3 almost coaxial, where the first arc
    of a door 0.7 m ahead leaves the Panda): at 12 deg/s the per-tick IK needs a joint faster than its limit; at a
    slower pace the same arc passes."""
    from drivers.arm.motion import POSTURE_GAIN_PER_S, Tracker
    from drivers.arm.trajectory import PathProfile
    from drivers.errors import JointSpeedError

    q0 = np.array([0.718, 0.081, -0.638, -1.529, 1.514, 3.363, 0.893])
    arm = IdealArm.panda(q0, control_period_s=1.0 / 240)
    kin, dt = arm.kin, arm.control_period_s
    assert np.linalg.svd(kin.jacobian(q0), compute_uv=False)[-1] < 0.01  # near a singularity
    T0 = kin.fk(q0)
    hinge = T0[:3, 3] + [0.15, 0.47, 0.0]  # a door's hinge 0.47 m to the grip's left, its front 15 cm ahead
    arc, length, speed = arc_path(T0, hinge, [0.0, 0.0, -1.0], turn=False), np.radians(12.0), np.radians(12.0)
    limits = MotionLimits(speed, 4 * speed, 40 * speed)
    track = Tracker(kin, arc, length, q0, kin.v_max * dt, POSTURE_GAIN_PER_S * dt, speed * dt)
    with pytest.raises(JointSpeedError, match=r"^ik: lost the Cartesian path at s = .*velocity limit"):
        track.plan(PathProfile(length, *(float(x[0]) for x in limits.arrays(1))), dt, q0)

    result, qs, dqs = _follow(arm, arc, length, limits)
    assert result.reason == "completed"
    assert arm.state().t > 1.5 * length / speed  # slowed down
    assert np.linalg.norm(kin.fk(arm.state().q)[:3, 3] - arc(length)[:3, 3]) < 1e-3
    assert np.all(np.abs(dqs) <= kin.v_max)
