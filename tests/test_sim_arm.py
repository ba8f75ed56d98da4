"""The simulated Panda: joint control, safety, gripper, a grasp that opens a drawer and can slip."""

import time

import numpy as np
import pybullet as pb
import pytest

from drivers.arm.base import Arm
from drivers.arm.motion import follow_cartesian_path, line_path, move_to_joints
from drivers.arm.robot_config import panda_sim_config
from drivers.arm.trajectory import MotionLimits
from drivers.errors import ArmError
from sim_fallback.arm import SimArm
from sim_fallback.scenario import Scenario
from sim_fallback.scripted import grasp_handle
from sim_fallback.world import SimWorld

PULL = MotionLimits(0.05, 0.3, 3.0)  # m/s, m/s^2, m/s^3 along the path


def _limits(world, arm):
    return panda_sim_config().motion_limits(arm.kin, 0.3)


def test_reaches_a_joint_target_faster_than_real_time():
    with SimWorld(Scenario.make("drawer", 0)) as world:
        arm = SimArm(world)
        assert isinstance(arm, Arm) and arm.control_period_s == pytest.approx(1 / 240)
        start = arm.state()
        assert start.gripper_width_m == pytest.approx(0.08, abs=1e-3) and len(arm.joint_names) == 7
        goal = start.q + np.array([0.3, -0.2, 0.2, 0.3, 0.3, -0.3, 0.4])
        wall0 = time.perf_counter()
        assert move_to_joints(arm, goal, _limits(world, arm))
        wall = time.perf_counter() - wall0
        for _ in range(60):
            arm.sync()
        end = arm.state()
        np.testing.assert_allclose(end.q, goal, atol=2e-3)
        assert np.abs(end.dq).max() < 1e-2 and end.tau is not None
        assert end.t == pytest.approx(world.time) and end.t > start.t
        assert (end.t - start.t) / wall > 2.0  # about 10x on an idle core


def test_safety_guard_stops_a_jump():
    with SimWorld(Scenario.make("drawer", 0)) as world:
        arm = SimArm(world)
        q = arm.state().q
        with pytest.raises(ArmError, match="jumps"):
            arm.command(q + 0.3)
        for _ in range(48):
            arm.sync()
        np.testing.assert_allclose(arm.state().q, q, atol=2e-3)  # held still
        assert not any(isinstance(value, SimWorld) for value in vars(arm).values())


def test_grasp_holds_the_handle_and_pulling_opens_the_drawer():
    with SimWorld(Scenario.make("drawer", 0)) as world:
        arm = SimArm(world)
        grasp_handle(world, arm, _limits(world, arm), target=0.05)
        width = arm.state().gripper_width_m
        assert 0.005 < width < 0.03  # closed on the bar, not on itself
        opening = world.truth().direction
        pull = line_path(arm.kin.fk(arm.state().q), opening)
        result = follow_cartesian_path(arm, arm.kin, pull, 0.05, PULL)
        assert result.reason == "completed"
        assert world.joint_value() == pytest.approx(0.05, abs=0.005)
        assert arm.state().gripper_width_m == pytest.approx(width, abs=1e-3)  # still holding

        arm.set_gripper(0.08)  # let go: pulling on moves the hand away from the handle
        for _ in range(120):
            arm.sync()
        follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), opening), 0.03, PULL)
        assert world.joint_value() == pytest.approx(0.05, abs=0.005)


@pytest.mark.parametrize(("friction_n", "slips"), [(40.0, False), (400.0, True)])
def test_grasp_slips_above_its_force_limit(friction_n, slips):
    with SimWorld(Scenario.make("drawer", 0)) as world:
        arm = SimArm(world, grasp_force_limit_n=60.0)
        grasp_handle(world, arm, _limits(world, arm), target=0.05)
        assert arm.state().gripper_width_m > 0.005
        # a stiff (40 N) or stuck (400 N) drawer: PyBullet's joint motor is the drawer's Coulomb friction
        pb.setJointMotorControl2(world.cabinet_id, 0, pb.VELOCITY_CONTROL, targetVelocity=0.0,
                                 force=friction_n, physicsClientId=world.client)
        opening = world.truth().direction
        follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), opening), 0.05, PULL)
        for _ in range(120):
            arm.sync()
        hand = arm.kin.fk(arm.state().q)[:3, 3]
        if slips:
            assert abs(world.joint_value()) < 0.005
            assert arm.state().gripper_width_m < 0.003  # fingers closed on nothing: a measurable slip
            assert np.linalg.norm(hand - world.handle_pose()[:3, 3]) > 0.03
        else:
            assert world.joint_value() == pytest.approx(0.05, abs=0.005)
            assert arm.state().gripper_width_m > 0.005
