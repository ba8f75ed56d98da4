"""Joint torques as a Damiao motor measures them: from its phase current, not from a torque sensor.

    measured = quantised(true + offset + bias(t) + noise)

- quantised: 12 bits over [-TMAX, TMAX], clipped to that range, the torque field of the feedback frame
  (drivers/arm/damiao.py; TMAX of the joint's motor model);
- offset: per joint, constant over an episode (the torque constant's and the current sensor's calibration error,
  the gear's friction at rest), normal with std `offset_share` x TMAX;
- bias(t): per joint, drifting slowly (the current sensor's offset warming up): an Ornstein-Uhlenbeck process with
  std `bias_share` x TMAX and correlation time `bias_time_s`, starting from its stationary spread;
- noise: white, std `noise_share` x TMAX per reading (the current sample's noise).

Sizes (`TorqueErrors`) are shares of TMAX, the full scale of the torque feedback (at or a little above the motor's
peak torque in the vendor's tables). They are engineering estimates, not measured on a Damiao motor (no published
figure was found; the sources looked at and what they give: docs/benchmarks.md, "Torque sensing model"). Every
draw comes from one seed, so an episode's signals repeat exactly.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.arm.robot_config import RobotConfig

TORQUE_BITS = 12  # the feedback frame's torque field


@dataclass(frozen=True)
class TorqueErrors:
    """The sizes of the errors, as shares of each motor's TMAX (and the bias's correlation time, s)."""

    noise_share: float = 0.003
    bias_share: float = 0.005
    bias_time_s: float = 120.0
    offset_share: float = 0.02

    @classmethod
    def none(cls) -> TorqueErrors:
        """Only the quantisation of the feedback frame."""
        return cls(0.0, 0.0, 120.0, 0.0)


class TorqueSensing:
    """Measured joint torques from true ones (N m), for joints whose motors have full scales `t_max` (N m).

    `measure(tau, t)` gives one reading at time t (s, not decreasing); readings at the same t share the bias and
    differ in their noise. `seed`: anything `numpy.random.default_rng` takes."""

    def __init__(self, t_max: Sequence[float], seed: int | Sequence[int] = 0,
                 errors: TorqueErrors = TorqueErrors()) -> None:
        self.t_max = np.asarray(t_max, float)
        if self.t_max.ndim != 1 or not np.all(self.t_max > 0):
            raise ValueError(f"torque full scales must be positive, one per joint, got {t_max}")
        self.errors = errors
        self._rng = np.random.default_rng(seed)
        n = len(self.t_max)
        self.offset = self._rng.normal(0.0, errors.offset_share, n) * self.t_max
        self.bias = self._rng.normal(0.0, errors.bias_share, n) * self.t_max
        self._t: float | None = None

    @classmethod
    def for_robot(cls, config: RobotConfig, seed: int | Sequence[int] = 0,
                  errors: TorqueErrors = TorqueErrors()) -> TorqueSensing:
        """The arm joints of `config`, each with its motor model's TMAX."""
        return cls([j.default_limits.t_max for j in config.joints], seed, errors)

    @property
    def step_n_m(self) -> np.ndarray:
        """The quantisation step of each joint (N m)."""
        return 2 * self.t_max / ((1 << TORQUE_BITS) - 1)

    def measure(self, tau: np.ndarray, t: float) -> np.ndarray:
        """One reading of true torques `tau` (N m) at time `t` (s)."""
        self._drift(t)
        noise = self._rng.normal(0.0, self.errors.noise_share, len(self.t_max)) * self.t_max
        return self.quantise(np.asarray(tau, float) + self.offset + self.bias + noise)

    def quantise(self, tau: np.ndarray) -> np.ndarray:
        """`tau` clipped to +-TMAX and rounded to the feedback frame's 12-bit grid (damiao.pack_feedback's)."""
        levels = (1 << TORQUE_BITS) - 1
        u = np.rint((np.clip(tau, -self.t_max, self.t_max) + self.t_max) / (2 * self.t_max) * levels)
        return u / levels * (2 * self.t_max) - self.t_max

    def _drift(self, t: float) -> None:
        """Advance the bias to time t: exact Ornstein-Uhlenbeck steps, any interval."""
        if self._t is not None and t > self._t:
            decay = np.exp(-(t - self._t) / self.errors.bias_time_s)
            spread = self.errors.bias_share * self.t_max * np.sqrt(1.0 - decay ** 2)
            self.bias = self.bias * decay + self._rng.normal(0.0, 1.0, len(self.t_max)) * spread
        if self._t is None or t > self._t:
            self._t = float(t)
