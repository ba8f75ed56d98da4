"""The arm protocol: one joint command per control cycle, below it the safety layer, above it motion code.

Motion code (drivers/arm/motion.py) runs the same loop on every arm:
    for each tick: q_ref, dq_ref = trajectory(t); arm.command(q_ref, dq_ref); arm.sync()
A real arm's `sync()` sleeps until the next tick of its control clock; the simulated arm's steps the
physics by one control period, so simulation runs faster than real time with identical code.

Like python-can's `BusABC`, the base class declares every capability the application uses, each optional one
with a default, so that no caller asks an arm what it is (`hasattr`, `isinstance`): an arm that measures no
motors reports none, one that needs no request to read its joints probes by doing nothing, one without
impedance gains ignores compliance.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from drivers.arm.kinematics import Kinematics
from drivers.arm.safety import SafetyGuard, SafetyLimits

GRIP_FORCE_N = 40.0  # the squeeze a gripper closes with unless told (N): the robot config's grip_force_n default


@dataclass(frozen=True)
class ArmState:
    """Measured state: joint positions (rad or m), velocities, torques (N m, None if not measured)."""

    t: float
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray | None
    gripper_width_m: float


class Arm(ABC):
    """Base class of every arm. Use as a context manager: leaving it always stops the arm.

    Every arm implements the abstract methods and sets, when built, `kin` (its kinematics: forward kinematics, IK,
    the URDF's limits) and `guard` (the safety check every `command` passes, holding the limits of its robot
    config: `RobotConfig.safety_guard`). The other capabilities have defaults below.
    """

    control_period_s: float = 0.002
    kin: Kinematics
    guard: SafetyGuard
    bus_channel: str | None = None  # the bus channel its motors answer on (None: no bus of its own)

    @property
    def limits(self) -> SafetyLimits:
        """The joint, velocity, acceleration and workspace limits its commands are held to (the guard's)."""
        return self.guard.limits

    @property
    @abstractmethod
    def joint_names(self) -> list[str]: ...

    def connect(self) -> None:
        """Open the bus / world and enable the motors (idempotent)."""

    def disconnect(self) -> None:
        """Stop and release; safe to call after any failure."""
        self.stop()

    @abstractmethod
    def state(self) -> ArmState: ...

    @abstractmethod
    def command(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Send one joint position (+ velocity feed-forward) command; checked by the safety layer."""

    @abstractmethod
    def sync(self) -> None:
        """Wait for the next control tick (real arm: wall clock; simulated: one physics period)."""

    @abstractmethod
    def set_gripper(self, width_m: float, force_n: float = GRIP_FORCE_N) -> None:
        """Command the gripper opening (0 = closed) with a force limit; returns at once."""

    @abstractmethod
    def stop(self) -> None:
        """Hold still and make safe (real arm: damp then disable motors). Idempotent, never raises."""

    def set_compliance(self, compliant: bool) -> None:
        """Softer joint gains while pulling a handle (arms with impedance/MIT gains); others ignore it."""

    def probe(self) -> None:
        """Refresh the measured state without enabling anything (a CAN arm asks every motor once); an arm whose
        state is always current has nothing to do."""

    def clear_errors(self) -> None:
        """Clear the motors' latched faults before enabling (motor drivers that latch them); others: nothing."""

    def commanded_q(self) -> np.ndarray | None:
        """The joint position last commanded (rad or m); None where the arm does not keep it."""
        return None

    def motor_states(self) -> list[dict]:
        """Every motor's state (name, CAN id, enabled, status) as left after stopping; none without motors."""
        return []

    def motor_report(self) -> list[dict]:
        """Every motor's reading while enabled (status, position, torque, temperatures); none without motors."""
        return []

    def time(self) -> float:
        return self.state().t

    def __enter__(self) -> Arm:
        self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.disconnect()
