"""Safety guard: every violated limit raises ArmError naming the joint and the limit."""

import numpy as np
import pytest

from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import panda_sim_config
from drivers.arm.robots import panda
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.arm.trajectory import joint_trajectory
from drivers.errors import ArmError

DT = 0.002


@pytest.fixture(scope="module")
def kin() -> Kinematics:
    return Kinematics.panda()


@pytest.fixture(scope="module")
def guard(kin) -> SafetyGuard:
    return SafetyGuard(SafetyLimits.for_robot(panda(), kin), kin.joint_names)


def _check(guard, kin, q, dq=None, q_prev=None, dq_prev=None, tool=None):
    q_prev = q if q_prev is None else q_prev
    tool = kin.fk(q)[:3, 3] if tool is None else tool
    guard.check(q, dq, q_prev, DT, tool, dq_prev)


def _stream(guard, kin, traj, speed: float = 1.0) -> tuple[float, float]:
    """Check every cycle of `traj` played `speed` times faster; the peak velocity and acceleration (per cycle, of
    the commands) as shares of their limits."""
    limits = guard.limits
    q_prev, dq_prev = traj.at(0.0)[:2]
    peak_v = peak_a = 0.0
    for t in np.append(np.arange(DT, traj.duration / speed, DT), traj.duration / speed):
        q, dq, _ = traj.at(t * speed)
        dq = dq * speed
        _check(guard, kin, q, dq, q_prev, dq_prev)
        peak_v = max(peak_v, float(np.max(np.abs(dq) / limits.v_max)))
        peak_a = max(peak_a, float(np.max(np.abs(dq - dq_prev) / DT / limits.a_max)))
        q_prev, dq_prev = q, dq
    return peak_v, peak_a


def test_a_planned_trajectory_passes_every_check(guard, kin):
    q0 = panda().q_ready
    limits = panda_sim_config().motion_limits(kin, 1.0)
    traj = joint_trajectory(q0, q0 + np.array([0.6, -0.3, 0.5, 0.4, -0.6, 0.3, 0.8]), limits)
    peak_v, peak_a = _stream(guard, kin, traj)
    assert peak_v > 0.99 and peak_a > 0.9  # it ran at the limits, so the checks were tested at them
    with pytest.raises(ArmError, match="exceeds its limit"):
        _stream(guard, kin, traj, speed=1.05)  # the same motion 5 % faster is refused


def test_position_limits_name_the_joint(guard, kin):
    q = panda().q_ready.copy()
    q[3] = 0.05  # panda_joint4 upper limit is 0
    with pytest.raises(ArmError, match=r"joint panda_joint4 position 0\.0500 rad is above its limit 0\.0000"):
        _check(guard, kin, q, tool=kin.fk(panda().q_ready)[:3, 3])
    q = panda().q_ready.copy()
    q[5] = -0.2
    with pytest.raises(ArmError, match="joint panda_joint6 position .* below its limit -0.0873"):
        _check(guard, kin, q, tool=kin.fk(panda().q_ready)[:3, 3])


def test_velocity_limit_names_the_joint(guard, kin):
    q = panda().q_ready
    dq = np.zeros(7)
    dq[6] = -3.0
    with pytest.raises(ArmError, match=r"joint panda_joint7 velocity -3\.000 rad/s exceeds its limit 2\.610"):
        _check(guard, kin, q, dq)


def test_jump_between_cycles_names_the_joint(guard, kin):
    q_prev = panda().q_ready
    q = q_prev.copy()
    q[1] += 0.1
    with pytest.raises(ArmError, match=r"joint panda_joint2 command jumps 0\.1000 rad in one 2\.0 ms cycle"):
        _check(guard, kin, q, q_prev=q_prev)
    q[1] = q_prev[1] + 0.012  # v_max * dt + tolerance = 0.01435 rad
    _check(guard, kin, q, q_prev=q_prev)


def test_a_step_from_where_a_pushed_arm_is_is_not_a_jump(guard, kin):
    q_prev = panda().q_ready
    measured = q_prev.copy()
    measured[4] += 0.03  # a held door pushed the compliant arm off its last command
    q = measured.copy()
    q[4] += 0.005
    guard.check(q, None, q_prev, 0.002, kin.fk(q)[:3, 3], q_measured=measured)
    with pytest.raises(ArmError, match="panda_joint5 command jumps"):
        guard.check(q, None, q_prev, 0.002, kin.fk(q)[:3, 3])
    far = q_prev.copy()
    far[4] -= 0.05  # away from both the last command and the arm
    with pytest.raises(ArmError, match="panda_joint5 command jumps"):
        guard.check(far, None, q_prev, 0.002, kin.fk(far)[:3, 3], q_measured=measured)


def test_acceleration_limit_names_the_joint(guard, kin):
    q = panda().q_ready
    dq_prev, dq = np.zeros(7), np.zeros(7)
    dq[2] = 0.1  # 50 rad/s^2 in one cycle
    with pytest.raises(ArmError, match=r"joint panda_joint3 acceleration 50\.00 rad/s\^2 exceeds its limit"):
        _check(guard, kin, q, dq, dq_prev=dq_prev)
    _check(guard, kin, q, dq)  # without a previous velocity (stream start) there is no acceleration check


def test_workspace_box_names_the_axis(guard, kin):
    q = panda().q_ready
    with pytest.raises(ArmError, match=r"tool position \(0\.450, 0\.000, 0\.010\) m leaves the .* along z"):
        _check(guard, kin, q, tool=np.array([0.45, 0.0, 0.01]))


def test_non_finite_and_misshaped_commands(guard, kin):
    q = panda().q_ready.copy()
    q[4] = np.nan
    with pytest.raises(ArmError, match="joint panda_joint5 position command is not finite"):
        _check(guard, kin, q, q_prev=panda().q_ready, tool=np.zeros(3))
    with pytest.raises(ArmError, match=r"shape \(6,\), expected \(7,\)"):
        _check(guard, kin, np.zeros(6), q_prev=np.zeros(7), tool=np.zeros(3))
