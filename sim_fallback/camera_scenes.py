"""Scenes for measuring the simulated camera: plain walls facing a camera (for the depth models' fill rate and
error). Visual only (no collision shapes): they change what the camera sees, not the physics.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb


def box(client: int, half: tuple[float, float, float], centre: np.ndarray, yaw: float,
        rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)) -> int:
    """A static, visual-only box (half extents in its own frame, turned `yaw` about z) : its body id."""
    shape = pb.createVisualShape(pb.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=client)
    quat = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
    return pb.createMultiBody(0.0, -1, shape, [float(v) for v in centre], quat, physicsClientId=client)


def look_along_x(height_m: float = 1.0) -> np.ndarray:
    """A camera pose at (0, 0, height) looking along the world's x axis, level."""
    T = np.eye(4)
    T[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    T[:3, 3] = [0.0, 0.0, height_m]
    return T


def wall(client: int, distance_m: float, height_m: float = 1.0, rgba=(0.8, 0.8, 0.8, 1.0)) -> int:
    """A 6 m square wall facing `look_along_x(height_m)` at `distance_m`."""
    return box(client, (0.01, 3.0, 3.0), np.array([distance_m + 0.01, 0.0, height_m]), 0.0, rgba)
