"""`--arm sim-can` end to end: the closed-loop episode drives the PyBullet Panda through the real CAN driver
(CanArm -> python-can virtual bus -> simulated Damiao motors -> PyBullet), and a motor fault ends it safely."""

import numpy as np

from deploy.config import Config
from deploy.control.episode import run_episode
from deploy.perception.oracle import OracleSegmenter
from drivers.arm.can_arm import CanArm
from drivers.arm.damiao import Status
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.devices import sim_can_arm
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

PANDA = load_robot_config("panda_sim")


def _episode(world, arm, target=0.2):
    config = Config().replace(opening={"task": "drawer", "target_distance_m": target})
    camera = SimCamera(world, intrinsics=d415_intrinsics(640, 480), seed=0, fps=config.opening.camera_hz, labels=True,
                       posed=True)
    return run_episode(camera, arm, arm.kin, OracleSegmenter(), config, None,
                       MotionLimits.for_robot(world.robot_spec, arm.kin, 0.3),
                       compliance=PANDA.compliance.gains())  # the robot config's, as `deploy open` runs it


def test_closed_loop_drawer_opening_through_the_can_driver():
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm = open_arm("sim-can", PANDA, world=world)
        assert isinstance(arm, CanArm) and not arm.realtime
        with arm:
            q0 = arm.state().q
            np.testing.assert_allclose(q0, world.scenario.q_start, atol=1e-3)
            result = _episode(world, arm)
        assert result.to_dict()["stop_reason"] == "target reached"
        assert world.joint_value() >= 0.19  # the truth, read after the episode


def test_motor_fault_during_an_episode_ends_it_with_the_joint_named():
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm, motors = sim_can_arm(PANDA, world)

        def fault_after_one_second():
            if world.clock.steps == 240:
                motors.motor("panda_joint2").faults.status = Status.MOS_OVER_TEMPERATURE

        world.clock.add_hook(fault_after_one_second)
        with arm:
            result = _episode(world, arm).to_dict()
        assert result["stop_reason"] == "arm error"
        assert "panda_joint2" in result["message"] and "mos-over-temperature" in result["message"]
        assert not any(m.enabled for m in motors.motors)
