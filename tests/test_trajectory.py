"""Ruckig trajectories: joint moves, braking, path-parameter profiles and online retargeting."""

import numpy as np
import pytest

from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import panda_sim_config
from drivers.arm.robots import panda
from drivers.arm.trajectory import (
    JointTrajectory,
    MotionLimits,
    OnlineRetargeter,
    PathProfile,
    joint_trajectory,
)

EPS = 1e-9


@pytest.fixture(scope="module")
def kin() -> Kinematics:
    return Kinematics.panda()


@pytest.fixture(scope="module")
def limits(kin) -> MotionLimits:
    return panda_sim_config().motion_limits(kin, 0.5)


def _samples(traj: JointTrajectory, dt: float = 0.002) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ts = np.append(np.arange(0.0, traj.duration, dt), traj.duration)
    q, dq, ddq = zip(*(traj.at(t) for t in ts), strict=True)
    return np.array(q), np.array(dq), np.array(ddq)


def _assert_within(traj: JointTrajectory, limits: MotionLimits) -> None:
    v_max, a_max, _ = limits.arrays(traj.at(0)[0].size)
    q, dq, ddq = _samples(traj)
    assert np.all(np.abs(dq) <= v_max + EPS)
    assert np.all(np.abs(ddq) <= a_max + EPS)
    # the sampled positions are consistent with the sampled velocities (finite differences)
    assert np.allclose(np.diff(q, axis=0)[:-1] / 0.002, (dq[1:-1] + dq[:-2]) / 2, atol=0.01)


def test_joint_trajectory_respects_limits_and_reaches_the_goal(kin, limits):
    rng = np.random.default_rng(0)
    for _ in range(20):
        q0, q1 = rng.uniform(kin.q_min, kin.q_max, (2, kin.dof))
        traj = joint_trajectory(q0, q1, limits)
        assert traj.duration > 0
        _assert_within(traj, limits)
        assert np.allclose(traj.at(0.0)[0], q0)
        q_end, dq_end, ddq_end = traj.at(traj.duration)
        assert np.allclose(q_end, q1, atol=1e-9) and np.allclose(dq_end, 0, atol=1e-9)
        assert np.allclose(ddq_end, 0, atol=1e-9)
        assert np.allclose(traj.at(traj.duration + 5.0)[0], q1)  # clamped after the end


def test_rest_to_rest_moves_follow_a_straight_line_in_joint_space(kin, limits):
    q0, q1 = kin.q_min * 0.5, kin.q_max * 0.5
    traj = joint_trajectory(q0, q1, limits)
    q, _, _ = _samples(traj)
    fraction = (q - q0) @ (q1 - q0) / np.dot(q1 - q0, q1 - q0)
    assert np.allclose(q, q0 + np.outer(fraction, q1 - q0), atol=1e-9)


def test_joint_trajectory_from_a_moving_start(kin, limits):
    q0 = panda().q_ready
    dq0 = np.full(kin.dof, 0.5)
    traj = joint_trajectory(q0, q0, limits, dq0=dq0)
    assert np.allclose(traj.at(0.0)[1], dq0)
    _assert_within(traj, limits)
    assert np.allclose(traj.at(traj.duration)[0], q0)


def test_zero_length_move_has_zero_duration(limits):
    q0 = panda().q_ready
    traj = joint_trajectory(q0, q0, limits)
    assert traj.duration == 0.0
    assert np.allclose(traj.at(1.0)[0], q0)


def test_stopping_brakes_to_rest_within_limits(kin, limits):
    q0, q1 = kin.q_min * 0.5, kin.q_max * 0.5
    traj = joint_trajectory(q0, q1, limits)
    t_stop = traj.duration / 2
    brake = traj.stopping(t_stop)
    q_stop, dq_stop, _ = traj.at(t_stop)
    assert np.allclose(brake.at(0.0)[0], q_stop) and np.allclose(brake.at(0.0)[1], dq_stop)
    assert 0 < brake.duration < traj.duration / 2
    _assert_within(brake, limits)
    assert np.allclose(brake.at(brake.duration)[1], 0.0, atol=1e-9)


def test_path_profile_reaches_its_length_at_rest():
    profile = PathProfile(0.3, v_max=0.1, a_max=0.5, j_max=5.0)
    ts = np.linspace(0, profile.duration, 500)
    s, ds = np.array([profile.at(t) for t in ts]).T
    assert s[0] == 0.0 and s[-1] == pytest.approx(0.3, abs=1e-12)
    assert ds[-1] == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.diff(s) >= -1e-12) and np.all(ds <= 0.1 + EPS)
    assert profile.duration == pytest.approx(0.3 / 0.1 + 0.1 / 0.5 + 0.5 / 5.0)  # L/v + v/a + a/j
    assert PathProfile(0.0, 0.1, 0.5, 5.0).duration == 0.0


def test_path_profile_stopping_continues_along_the_path():
    profile = PathProfile(1.0, v_max=0.5, a_max=1.0, j_max=10.0)
    t = profile.duration / 2
    s_stop, ds_stop = profile.at(t)
    brake = profile.stopping(t)
    assert brake.at(0.0) == pytest.approx((s_stop, ds_stop))
    s_end, ds_end = brake.at(brake.duration)
    assert s_stop < s_end <= 1.0 and ds_end == pytest.approx(0.0, abs=1e-12)


def test_online_retargeter_follows_a_moving_target(kin, limits):
    dt = 0.002
    q0 = panda().q_ready
    retargeter = OnlineRetargeter(q0, limits, dt)
    v_max, a_max, _ = limits.arrays(kin.dof)
    target = q0 + 0.3
    q_prev, dq_prev = q0, np.zeros(kin.dof)
    for k in range(5000):
        if k == 100:
            target = q0 - 0.2  # the goal changes while moving
        q, dq, _ = retargeter.step(target)
        assert np.all(np.abs(dq) <= v_max + EPS)
        assert np.all(np.abs(dq - dq_prev) / dt <= a_max + 1e-6)
        assert np.all(np.abs(q - q_prev) <= v_max * dt + EPS)
        q_prev, dq_prev = q, dq
        if retargeter.finished:
            break
    assert retargeter.finished and k > 100
    assert np.allclose(q, target, atol=1e-9)


def test_invalid_input_raises_value_error(limits):
    q0 = panda().q_ready
    with pytest.raises(ValueError, match="finite and positive"):
        joint_trajectory(q0, q0 + 0.1, MotionLimits(0.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="goal position"):
        joint_trajectory(q0, np.full(7, np.nan), limits)
    with pytest.raises(ValueError, match="path length"):
        PathProfile(-0.1, 0.1, 0.5, 5.0)
    with pytest.raises(ValueError, match="target position"):
        OnlineRetargeter(q0, limits, 0.002).step(np.full(7, np.inf))
