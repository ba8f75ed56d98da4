"""Axis errors for evaluation: angle between axis lines and distance between them near the object."""

from __future__ import annotations

import numpy as np


def axis_angle_error_deg(d_true: np.ndarray, d_est: np.ndarray) -> float:
    """Angle between the two axis lines in degrees, in [0, 90] (the directions' signs are ignored)."""
    a, b = _unit(d_true, "d_true"), _unit(d_est, "d_est")
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b))))


def axis_position_error_m(
    origin_true: np.ndarray,
    dir_true: np.ndarray,
    origin_est: np.ndarray,
    dir_est: np.ndarray,
    at: np.ndarray | None = None,
) -> float:
    """Distance (m) from the point of the true axis nearest `at` to the estimated axis line.

    `at` is where the error matters (the object's centre); default the true origin.
    """
    o_t, o_e = np.asarray(origin_true, dtype=np.float64), np.asarray(origin_est, dtype=np.float64)
    d_t, d_e = _unit(dir_true, "dir_true"), _unit(dir_est, "dir_est")
    at = o_t if at is None else np.asarray(at, dtype=np.float64)
    q = o_t + ((at - o_t) @ d_t) * d_t
    offset = q - o_e
    return float(np.linalg.norm(offset - (offset @ d_e) * d_e))


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(3)
    norm = np.linalg.norm(v)
    if not (np.isfinite(norm) and norm > 1e-12):
        raise ValueError(f"axis metrics: {name} must be a finite non-zero 3-vector, got {v.tolist()}")
    return v / norm
