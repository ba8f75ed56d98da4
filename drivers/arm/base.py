"""The arm protocol: one joint command per control cycle, below it the safety layer, above it motion code.

Motion code (drivers/arm/motion.py) runs the same loop on every arm:
    for each tick: q_ref, dq_ref = trajectory(t); arm.command(q_ref, dq_ref); arm.sync()
A real arm's `sync()` sleeps until the next tick of its control clock; the simulated arm's steps the
physics by one control period, so simulation runs faster than real time with identical code.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ArmState:
    """Measured state: joint positions (rad or m), velocities, torques (N m, None if not measured)."""

    t: float
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray | None
    gripper_width_m: float


class Arm(ABC):
    """Base class of every arm. Use as a context manager: leaving it always stops the arm."""

    control_period_s: float = 0.002

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
    def set_gripper(self, width_m: float, force_n: float = 40.0) -> None:
        """Command the gripper opening (0 = closed) with a force limit; returns at once."""

    @abstractmethod
    def stop(self) -> None:
        """Hold still and make safe (real arm: damp then disable motors). Idempotent, never raises."""

    def set_compliance(self, compliant: bool) -> None:
        """Softer joint gains while pulling a handle (arms with impedance/MIT gains); others ignore it."""

    def time(self) -> float:
        return self.state().t

    def __enter__(self) -> Arm:
        self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.disconnect()
