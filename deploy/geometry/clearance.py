"""Whether a parallel gripper moving through tool poses keeps clear of the scene the camera saw (pure functions, base
frame, metres).

The gripper is a few boxes in its tool frame (z: approach, y: the fingers' closing direction); the scene is the first
frame's points with the part being opened left out (it moves with the gripper). A pose touches the scene when a
scene point lies inside one of the boxes grown by the clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class ToolBox:
    """A box of the gripper: `centre` and `half` sizes (m) in the tool frame, and its `name`."""

    name: str
    centre: tuple[float, float, float]
    half: tuple[float, float, float]


def parallel_gripper(max_opening_m: float) -> tuple[ToolBox, ...]:
    """A parallel gripper around a tool frame at its finger pads: two fingers 5 cm long either side of the opening,
    and the hand behind them, as wide as the opening plus its finger guides and 6 cm thick (a Franka hand is
    20 x 6.3 cm); the wrist behind the hand is left out (the fingers and hand reach the scene first)."""
    half_open = max_opening_m / 2
    return (ToolBox("fingers", (0.0, 0.0, -0.02), (0.01, half_open + 0.01, 0.03)),
            ToolBox("hand", (0.0, 0.0, -0.08), (0.032, half_open + 0.06, 0.03)))


@dataclass(frozen=True)
class Contact:
    """Where a pose of the path would touch the scene: the pose's index, the gripper box, the scene point."""

    index: int
    box: str
    point: np.ndarray


def first_contact(scene: cKDTree, poses: list[np.ndarray], boxes: tuple[ToolBox, ...],
                  clearance_m: float) -> Contact | None:
    """The first of `poses` (4x4 tool poses, base frame) at which a scene point lies inside a gripper box grown by
    `clearance_m`; None when the whole path keeps clear."""
    points = scene.data
    for i, T in enumerate(poses):
        R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
        for box in boxes:
            centre, half = np.array(box.centre), np.array(box.half) + clearance_m
            near = scene.query_ball_point(p + R @ centre, float(np.linalg.norm(half)))
            if not near:
                continue
            local = (points[near] - p) @ R - centre
            inside = np.all(np.abs(local) <= half, axis=1)
            if inside.any():
                return Contact(i, box.name, points[near][np.argmax(inside)])
    return None


def line_poses(T_from: np.ndarray, T_to: np.ndarray, step_m: float) -> list[np.ndarray]:
    """Poses from `T_from` to `T_to` (same orientation) every `step_m` or finer, both ends included."""
    T_from, T_to = np.asarray(T_from, float), np.asarray(T_to, float)
    n = max(1, int(np.ceil(np.linalg.norm(T_to[:3, 3] - T_from[:3, 3]) / step_m)))
    poses = []
    for k in range(n + 1):
        T = T_to.copy()
        T[:3, 3] = T_from[:3, 3] + (T_to[:3, 3] - T_from[:3, 3]) * k / n
        poses.append(T)
    return poses


def standing_out(points: np.ndarray, origin: np.ndarray, right: np.ndarray, up: np.ndarray, normal: np.ndarray,
                 half_size: tuple[float, float], plane_band_m: float, part_depth_m: float) -> np.ndarray:
    """The scene a gripper at a front can touch: the `points` standing more than `plane_band_m` out of the front's
    plane (`origin`, unit `right`, `up`, outward `normal`), where neighbours' handles, a counter's overhang and side
    walls are (the fronts' plane and what lies behind it the fingers never pass), less the front's own handle: what
    stands up to `part_depth_m` out of the front's rectangle (`half_size`: half its width and height)."""
    d = np.asarray(points, float).reshape(-1, 3) - origin
    s, z, offset = d @ right, d @ up, d @ normal
    on_part = (np.abs(s) <= half_size[0]) & (np.abs(z) <= half_size[1]) & (offset <= part_depth_m)
    return points[(offset > plane_band_m) & ~on_part]
