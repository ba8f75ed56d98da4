"""Arms: one protocol (`Arm`); kinematics, trajectories and safety shared by every implementation."""

from drivers.arm.base import Arm, ArmState

__all__ = ["Arm", "ArmState"]
