"""Grasp geometry of a parallel gripper on a bar handle (pure functions, base frame, metres, z up): shared by the
opening policy (a handle seen by the camera) and the simulator's scripted openings (the true handle)."""

from __future__ import annotations

import numpy as np

UP = np.array([0.0, 0.0, 1.0])
GRASP_DEPTH_M = 0.01  # tool frame this far past the grip centre: the bar sits inside the finger pads
GRASP_PITCH_RAD = 0.25  # approach tilted down: keeps the Panda's wrist (joint 6) off its upper limit
FROM_ABOVE_RAD = (0.7, 1.1)  # tilted steeply down, tried after the usual grasps: a handle below the arm's usual reach
# grasped from above (the arm's low reach bands, drivers/arm/robots.py Reach, are where these pull it)
LIMIT_MARGIN_RAD = 0.1  # planned configurations stay this far inside the joint limits


def grasp_pose(center: np.ndarray, normal: np.ndarray, bar: np.ndarray, depth_m: float = GRASP_DEPTH_M,
               pitch_rad: float = GRASP_PITCH_RAD) -> np.ndarray:
    """Tool pose (4x4) grasping a bar at `center` on a front facing `normal` (unit, outward): approach (tool z)
    into the front tilted down by `pitch_rad`, fingers (tool y) across the bar, tool x along it (up for a
    vertical bar, to the tool's left-hand side for a horizontal one, which keeps the Panda's last joint
    mid-range)."""
    z = -np.cos(pitch_rad) * np.asarray(normal, float) - np.sin(pitch_rad) * UP
    bar = np.asarray(bar, float)
    x = bar - z * (z @ bar)
    if np.linalg.norm(x) < 1e-6:  # bar along the approach: any finger direction across it
        x = np.cross(z, UP)
    x /= np.linalg.norm(x)
    reference = UP if abs(bar @ UP) > np.sqrt(0.5) else np.cross(z, UP)
    if x @ reference < 0:
        x = -x
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = np.asarray(center, float) + depth_m * z
    return T


def pregrasp_pose(T_grasp: np.ndarray, distance_m: float) -> np.ndarray:
    """The grasp pose backed off `distance_m` along the approach axis (tool z)."""
    T = np.array(T_grasp, float)
    T[:3, 3] -= distance_m * T[:3, 2]
    return T


def approach_poses(T_grasp: np.ndarray, approach_m: float, steps: int) -> list[np.ndarray]:
    """A straight approach to the grasp pose over its last `approach_m`: `steps` poses from the pre-grasp pose on,
    the grasp pose itself not included."""
    return [pregrasp_pose(T_grasp, approach_m * (steps - k) / steps) for k in range(steps)]
