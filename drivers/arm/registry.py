"""The arm kinds (`--arm`): Damiao motors over CAN and an ideal kinematic arm; other packages add theirs (the
simulated Panda and the CAN driver on simulated motors register from sim_fallback).

`open_arm(spec, robot)` builds one, not yet connected: use it as a context manager (enter enables, exit stops).
Kinds that talk to their motors over a bus also register a factory of that bare bus (`bus`), for bring-up
commands that address the motors directly (scan, disable, set zero).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from drivers.errors import ArmError
from drivers.registry import Registry

if TYPE_CHECKING:
    from drivers.arm.base import Arm
    from drivers.arm.can_bus import CanBus
    from drivers.arm.robot_config import RobotConfig

ARMS: Registry[Arm] = Registry("arm", ArmError)  # factories: factory(argument, robot, **options)
ARMS.register("can", "drivers.arm.registry:open_can", "Damiao motors over CAN (hardware)",
              hardware=True, bus="drivers.arm.registry:open_can_bus")
ARMS.register("ideal", "drivers.arm.registry:open_ideal", "kinematic, no bus")


def open_arm(spec: str, robot: RobotConfig, **options: object) -> Arm:
    """The arm named by `spec` for `robot`; `options` go to its factory (simulated kinds take `world`)."""
    return ARMS.open(spec, robot, **options)


def open_can(_argument: str, robot: RobotConfig) -> Arm:
    from drivers.arm.can_arm import CanArm
    from drivers.arm.can_bus import CanBus

    robot.can.require_hardware(robot.label)
    return CanArm(robot, CanBus.from_config(robot.can))


def open_can_bus(robot: RobotConfig) -> tuple[CanBus, None]:
    """The robot config's CAN bus, no arm on top; no simulated motors behind it."""
    from drivers.arm.can_bus import CanBus

    robot.can.require_hardware(robot.label)
    return CanBus.from_config(robot.can), None


def open_ideal(_argument: str, robot: RobotConfig) -> Arm:
    import numpy as np

    from drivers.arm.ideal import IdealArm

    kin = robot.kinematics()
    width = robot.gripper.max_width_m if robot.gripper else 0.0
    return IdealArm(kin, robot.safety_guard(kin), np.array(robot.q_ready), robot.control_period_s, width)
