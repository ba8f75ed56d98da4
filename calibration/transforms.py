"""Small rigid-transform helpers (4x4 homogeneous, metres): inverse, mean, spread, errors."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from scipy.spatial.transform import Rotation


def inv(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform."""
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


def from_rt(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A 4x4 transform from a rotation (3x3 or Rodrigues vector) and a translation."""
    R = np.asarray(R, float)
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(R.reshape(3, 1))[0] if R.size == 3 else R
    T[:3, 3] = np.asarray(t, float).ravel()
    return T


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle of a rotation matrix, degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))))


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(translation mm, rotation deg) between two poses."""
    return (float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]) * 1e3),
            rotation_angle_deg(T_a[:3, :3].T @ T_b[:3, :3]))


def mean_pose(poses: Sequence[np.ndarray]) -> np.ndarray:
    """Mean position and chordal-L2 mean rotation of several poses."""
    stack = np.asarray(poses)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_matrix(stack[:, :3, :3]).mean().as_matrix()
    T[:3, 3] = stack[:, :3, 3].mean(axis=0)
    return T


def spread(poses: Sequence[np.ndarray]) -> tuple[float, float]:
    """RMS distance (mm) and RMS angle (deg) of poses around their mean: how much a frame that should be
    fixed moves between samples."""
    mean = mean_pose(poses)
    errors = np.array([pose_error(mean, T) for T in poses])
    return float(np.sqrt(np.mean(errors[:, 0] ** 2))), float(np.sqrt(np.mean(errors[:, 1] ** 2)))
