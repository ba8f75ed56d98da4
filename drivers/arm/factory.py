"""Build an arm from a robot config: "can" (Damiao motors on the configured CAN bus) or "ideal" (kinematic).

"sim" and "sim-can" need the PyBullet world: `sim_fallback.arm_factory.open_arm` builds them (and these two).
"""

from __future__ import annotations

import numpy as np

from drivers.arm.base import Arm
from drivers.arm.can_arm import CanArm
from drivers.arm.can_bus import CanBus
from drivers.arm.ideal import IdealArm
from drivers.arm.robot_config import RobotConfig
from drivers.arm.safety import SafetyGuard
from drivers.errors import ArmError

DRIVER_ARMS = ("can", "ideal")


def open_arm(spec: str, config: RobotConfig) -> Arm:
    """An arm of kind `spec`, not yet connected: use it as a context manager (enter enables, exit stops)."""
    if spec == "can":
        return CanArm(config, CanBus.from_config(config.can))
    if spec == "ideal":
        kin = config.kinematics()
        guard = SafetyGuard(config.safety_limits(kin), config.joint_names)
        width = config.gripper.max_width_m if config.gripper else 0.0
        return IdealArm(kin, guard, np.array(config.q_ready), config.control_period_s, width)
    raise ArmError(f"arm {spec!r} is not one of {', '.join(DRIVER_ARMS)} (sim and sim-can are built by "
                   "sim_fallback.arm_factory.open_arm)")
