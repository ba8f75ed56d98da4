"""Small frozen value types shared by the geometry functions (metres, base frame, z up)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np


class JointType(str, Enum):
    PRISMATIC = "prismatic"
    REVOLUTE = "revolute"


@dataclass(frozen=True)
class Box:
    """An oriented box: `rotation` columns are the box axes, `extent` the full side lengths (m)."""

    center: np.ndarray
    rotation: np.ndarray
    extent: np.ndarray

    @property
    def volume(self) -> float:
        return float(np.prod(self.extent))

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Points (N,3) expressed in the box frame (origin at the centre)."""
        return (np.asarray(points, float) - self.center) @ self.rotation

    def contains(self, points: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Boolean mask of the points inside the box grown by `margin_m` on every side."""
        local = np.abs(self.to_local(points))
        return np.all(local <= self.extent / 2 + margin_m, axis=1)

    def corners(self) -> np.ndarray:
        """The 8 corners (8,3)."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        return self.center + (signs * self.extent / 2) @ self.rotation.T


@dataclass(frozen=True)
class Axis:
    """A joint axis: a line through `origin` along unit `direction`.

    For a prismatic joint `direction` is the opening direction; for a revolute joint opening is a
    positive (right-handed) rotation about `direction`. `residual_m` is the fit's RMS residual and
    `confidence` in [0, 1] says how much the estimate can be trusted; `direction_sigma_deg`, when the
    estimator measures it, is the direction's standard deviation.
    """

    joint_type: JointType
    origin: np.ndarray
    direction: np.ndarray
    confidence: float = 1.0
    residual_m: float = 0.0
    radius_m: float | None = None
    direction_sigma_deg: float | None = None

    def to_dict(self) -> dict:
        return {
            "joint_type": self.joint_type.value,
            "origin": [float(v) for v in self.origin],
            "direction": [float(v) for v in self.direction],
            "radius_m": None if self.radius_m is None else float(self.radius_m),
            "residual_m": float(self.residual_m),
            "confidence": float(self.confidence),
            "direction_sigma_deg": None if self.direction_sigma_deg is None else float(self.direction_sigma_deg),
        }


@dataclass(frozen=True)
class NoAxis:
    """No estimate yet, with the reason (e.g. "not enough motion yet: 4 mm of 10 mm")."""

    reason: str
    details: dict = field(default_factory=dict)


AxisResult = Axis | NoAxis
