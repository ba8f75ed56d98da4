"""The Damiao motor models: the ranges their MIT frames map onto (PMAX, VMAX, TMAX), by model name."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MotorLimits:
    """The ranges the MIT frame maps onto (rad, rad/s, N m): the motor's PMAX, VMAX and TMAX registers."""

    p_max: float
    v_max: float
    t_max: float

    def __post_init__(self) -> None:
        if not all(math.isfinite(x) and x > 0 for x in (self.p_max, self.v_max, self.t_max)):
            raise ValueError(f"motor limits must be finite and positive, got {self}")


# Factory defaults of PMAX / VMAX / TMAX per model; the driver reads the registers at connect instead.
MODELS: dict[str, MotorLimits] = {
    "DM3507": MotorLimits(12.5, 50.0, 5.0),
    "DM4310": MotorLimits(12.5, 30.0, 10.0),
    "DM4310_48V": MotorLimits(12.5, 50.0, 10.0),
    "DM4340": MotorLimits(12.5, 8.0, 28.0),
    "DM4340_48V": MotorLimits(12.5, 10.0, 28.0),
    "DM6006": MotorLimits(12.5, 45.0, 20.0),
    "DM8006": MotorLimits(12.5, 45.0, 40.0),
    "DM8009": MotorLimits(12.5, 45.0, 54.0),
    "DM10010L": MotorLimits(12.5, 25.0, 200.0),
    "DM10010": MotorLimits(12.5, 20.0, 200.0),
    "DMH3510": MotorLimits(12.5, 280.0, 1.0),
    "DMH6215": MotorLimits(12.5, 45.0, 10.0),
    "DMG6220": MotorLimits(12.5, 45.0, 10.0),
}
