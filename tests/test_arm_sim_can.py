"""`--arm sim-can` end to end: the closed-loop episode drives the PyBullet Panda through the real CAN driver
(CanArm -> python-can virtual bus -> simulated Damiao motors -> PyBullet), and a motor fault ends it safely."""

import numpy as np
from episodes import sim_episode

from deploy.control.state import StopReason
from drivers.arm.can_arm import CanArm
from drivers.arm.damiao import Status
from sim_fallback.can_motors import motors_on


def test_closed_loop_drawer_opening_through_the_can_driver():
    started = {}

    def check_start(world, arm):
        assert isinstance(arm, CanArm) and not arm.realtime
        np.testing.assert_allclose(arm.state().q, world.scenario.q_start, atol=1e-3)
        started["checked"] = True

    ran = sim_episode(arm="sim-can", target=0.2, setup=check_start, resolution=(640, 480))
    assert started and ran.result.stop_reason is StopReason.TARGET_REACHED, ran.result.message
    assert ran.true_opening >= 0.19  # the truth, read after the episode


def test_motor_fault_during_an_episode_ends_it_with_the_joint_named():
    seen = {}

    def fault_after_one_second(world, arm):
        motors = seen["motors"] = motors_on(arm.bus_channel)

        def fault():
            if world.clock.steps == 240:
                motors.motor("panda_joint2").faults.status = Status.MOS_OVER_TEMPERATURE

        world.clock.add_hook(fault)

    result = sim_episode(arm="sim-can", target=0.2, setup=fault_after_one_second, resolution=(640, 480)).result
    assert result.stop_reason is StopReason.ARM_ERROR
    assert "panda_joint2" in result.message and "mos-over-temperature" in result.message
    assert not any(m.enabled for m in seen["motors"].motors)
