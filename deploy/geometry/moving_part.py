"""The moving part: points outside the first frame's body box, cleaned by the radius filter."""

from __future__ import annotations

import numpy as np

from deploy.geometry.radius_filter import FILTER_PROFILES, radius_filter
from deploy.geometry.types import Box

_SIM = FILTER_PROFILES["sim"]


def moving_part(
    points: np.ndarray,
    body_box: Box,
    margin_m: float = 0.01,
    radius_m: float = _SIM.radius_m,
    eps: int = _SIM.eps,
) -> np.ndarray:
    """(M,3) points outside `body_box` grown by `margin_m`, kept by the radius filter (radius_m, eps)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return radius_filter(points[~body_box.contains(points, margin_m)], radius_m, eps)
