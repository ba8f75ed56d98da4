"""Faults of the simulated CAN arm written as text, `KIND[:JOINT][@SECONDS]` (the CLI's `--sim-fault`), so that
users can rehearse what their setup does when the bus or a motor fails.

JOINT is a joint name of the robot config or `gripper` (default: the first joint); SECONDS is the motors' clock,
i.e. seconds of the arm running (default 0: at once). Bus faults (bus-off, error-passive) take no joint.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from drivers.arm.damiao import Status
from drivers.errors import ArmError

if TYPE_CHECKING:
    from sim_fallback.can_motors import SimMotorBus

DELAY_S = 0.05  # the `delay` fault: replies this late (the default feedback timeout is 20 ms)
BUS_FAULTS = {
    "bus-off": "the bus goes bus-off: one error frame, then no motor answers",
    "error-passive": "the controller reports error-passive (one error frame); the motors keep answering",
    "cable-pulled": "the cable to the motors is cut: no frame reaches them, none comes back, and no error frame",
}
MOTOR_FAULTS = {
    "silent": "the motor stops answering and ignores every frame (it stays enabled)",
    "frame-loss": "every reply of the motor is lost; it still obeys commands",
    "delay": f"the motor's replies arrive {DELAY_S * 1e3:.0f} ms late",
}
STATUS_FAULTS = {
    "over-voltage": Status.OVER_VOLTAGE, "under-voltage": Status.UNDER_VOLTAGE,
    "over-current": Status.OVER_CURRENT, "over-temperature": Status.MOS_OVER_TEMPERATURE,
    "coil-over-temperature": Status.COIL_OVER_TEMPERATURE, "communication-lost": Status.COMMUNICATION_LOST,
    "overload": Status.OVERLOAD,
}
KINDS = [*BUS_FAULTS, *MOTOR_FAULTS, *STATUS_FAULTS]


@dataclass(frozen=True)
class SimFault:
    """One fault: `kind` (one of KINDS), on motor `joint` (None: the first joint; bus faults: none), `at_s`
    seconds into the run."""

    kind: str
    joint: str | None = None
    at_s: float = 0.0

    @classmethod
    def parse(cls, text: str) -> SimFault:
        """`KIND[:JOINT][@SECONDS]`; ValueError naming what is wrong and what is allowed."""
        spec, _, when = text.strip().partition("@")
        kind, _, joint = spec.partition(":")
        kind = kind.strip().lower()
        if kind not in KINDS:
            raise ValueError(f"{text!r}: unknown fault kind {kind!r}; one of {', '.join(KINDS)}")
        if joint and kind in BUS_FAULTS:
            raise ValueError(f"{text!r}: {kind} is a fault of the whole bus: drop ':{joint}'")
        try:
            at_s = float(when) if when else 0.0
        except ValueError:
            raise ValueError(f"{text!r}: {when!r} is not a number of seconds (write e.g. {kind}@1.5)") from None
        if not 0.0 <= at_s < float("inf"):
            raise ValueError(f"{text!r}: the time must be a finite number of seconds >= 0")
        return cls(kind, joint.strip() or None, at_s)

    def schedule(self, motors: SimMotorBus) -> None:
        """Break `motors` at `at_s` on their clock (at once if that has passed); ArmError for an unknown joint."""
        if self.kind not in BUS_FAULTS:
            self._motor(motors)  # an unknown joint fails now, not when the fault is due
        motors.schedule(self.at_s, lambda: self.apply(motors))

    def apply(self, motors: SimMotorBus) -> None:
        """Break `motors` now."""
        if self.kind == "bus-off":
            motors.inject_bus_off()
        elif self.kind == "error-passive":
            motors.inject_error_passive()
        elif self.kind == "cable-pulled":
            motors.bus_dead = True
        else:
            faults = self._motor(motors).faults
            if self.kind == "silent":
                faults.silent = True
            elif self.kind == "frame-loss":
                faults.drop_rate = 1.0
            elif self.kind == "delay":
                faults.delay_s = DELAY_S
            else:
                faults.status = STATUS_FAULTS[self.kind]

    def _motor(self, motors: SimMotorBus):
        names = [getattr(m, "name", "gripper") for m in motors.config.motors]
        name = self.joint or names[0]
        if name not in names:
            raise ArmError(f"--sim-fault {self.kind}:{name}: no motor {name!r} in "
                           f"{motors.config.label}; one of {', '.join(names)}")
        return motors.motor(name)
