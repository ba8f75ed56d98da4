"""Adding an arm family takes a driver, a registry line and a robot config: nothing else in the code changes.

The family here is registered from this test module: a position-servo Panda in the simulated world that measures no
joint torques (as many hobby arms: its pulls are then stiff, bounded by the tracking error, not compliant) and has
no motors to report, no bus, no probe request. It implements only the `Arm` protocol's required members; the
application (rig, session, episode, run folder) asks it nothing else and runs a whole opening with it."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.control.session import OpenRequest, open_object
from deploy.control.state import StopReason
from drivers.arm.base import GRIP_FORCE_N, Arm, ArmState
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import PANDA_SIM_CONFIG, RobotConfig
from sim_fallback.arm import SimArm

KIND = "servo-panda"


class ServoPanda(Arm):
    """The driver (file 1 of 3): the simulated world's Panda behind position servos, its torques not measured."""

    def __init__(self, robot: RobotConfig, world) -> None:
        self.kin = robot.kinematics()
        self.guard = robot.safety_guard(self.kin)
        self._servos = SimArm(world, self.kin, self.guard)
        self.control_period_s = self._servos.control_period_s

    @property
    def joint_names(self) -> list[str]:
        return self.kin.joint_names

    def state(self) -> ArmState:
        s = self._servos.state()
        return ArmState(s.t, s.q, s.dq, None, s.gripper_width_m)

    def command(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        self._servos.command(q, dq)

    def sync(self) -> None:
        self._servos.sync()

    def set_gripper(self, width_m: float, force_n: float = GRIP_FORCE_N) -> None:
        self._servos.set_gripper(width_m, force_n)

    def stop(self) -> None:
        self._servos.stop()


def open_servo_panda(_argument: str, robot: RobotConfig, world=None) -> ServoPanda:
    return ServoPanda(robot, world)


@pytest.fixture
def servo_panda(monkeypatch, tmp_path):
    """The registry line (file 2) and the robot config (file 3); the registry is restored afterwards."""
    monkeypatch.setitem(ARMS._entries, KIND, None)
    ARMS.register(KIND, f"{__name__}:open_servo_panda", "position-servo Panda (no torque sensing)", simulated=True)
    config = tmp_path / "servo_panda.toml"
    config.write_text(PANDA_SIM_CONFIG.read_text().replace('name = "panda-sim"', f'name = "{KIND}"'))
    return config


def test_an_arm_family_registered_elsewhere_runs_a_whole_simulated_opening(servo_panda):
    request = OpenRequest(task="drawer", scene="drawer", distance_m=0.15, arm=KIND, robot=servo_panda,
                          segmenter="rgbd", seed=0, split="train", world="box")
    result = open_object(request, keep_run_dir=False)
    assert result["arm"] == KIND and "motors" not in result  # no motors of its own to report
    assert result["stop_reason"] == StopReason.TARGET_REACHED, result["message"]
    assert result["success"] and result["true_opened_m"] >= 0.15
    assert result["peak_pull_force_n"] == 0.0  # no torques measured: no force read, stiff pulls


def test_the_new_family_gets_every_optional_capability_from_the_protocol(servo_panda):
    from drivers.arm.robot_config import load_robot_config
    from sim_fallback.scenario import Scenario
    from sim_fallback.world import SimWorld

    robot = load_robot_config(servo_panda)
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm = ARMS.open(KIND, robot, world=world)
        arm.probe()
        arm.clear_errors()
        arm.set_compliance(True)
        assert arm.motor_states() == [] and arm.motor_report() == [] and arm.bus_channel is None
        assert arm.limits is arm.guard.limits
        np.testing.assert_array_equal(arm.limits.q_max, robot.safety_limits(arm.kin).q_max)
