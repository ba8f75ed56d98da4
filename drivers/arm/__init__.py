"""Arms: one protocol (`drivers.arm.base.Arm`), kinds chosen by a string (`drivers.arm.registry`); kinematics,
trajectories, safety and motion code shared by every implementation."""
