"""Whether a parallel gripper moving through tool poses keeps clear of the scene the camera saw (pure functions, base
frame, metres).

The gripper is a few boxes in its tool frame (z: approach, y: the fingers' closing direction); the scene is the first
frame's points with the part being opened left out (it moves with the gripper). A pose touches the scene when a
scene point lies within the clearance of one of the boxes (or, for a negative clearance, that deep inside one).
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


def parallel_gripper(opening_m: float, max_opening_m: float) -> tuple[ToolBox, ...]:
    """A parallel gripper opened `opening_m` around a tool frame between its finger pads, as a Franka hand's meshes
    give it: fingers 2 cm wide either side of the opening, 5.4 cm long to 0.7 cm past the tool frame, tapering from
    2.6 cm thick at the hand to 1.4 cm at the tip (three steps); the hand behind them, 9.2 cm deep, as wide as the
    widest opening plus 6 cm each side (20 cm), 4 cm thick in its half nearer the fingers and 6.4 cm in the other; the
    wrist behind the hand is left out (the fingers and hand reach the scene first)."""
    half_open = opening_m / 2
    return (ToolBox("fingertips", (0.0, 0.0, -0.0015), (0.01, half_open + 0.015, 0.0085)),
            ToolBox("fingers", (0.0, 0.0, -0.0185), (0.01, half_open + 0.02, 0.0085)),
            ToolBox("fingers", (0.0, 0.0, -0.037), (0.01, half_open + 0.026, 0.01)),
            ToolBox("hand", (0.0, 0.0, -0.062), (0.02, max_opening_m / 2 + 0.06, 0.023)),
            ToolBox("hand", (0.0, 0.0, -0.108), (0.032, max_opening_m / 2 + 0.06, 0.023)))


@dataclass(frozen=True)
class Contact:
    """Where a pose of the path would touch the scene: the pose's index, the gripper box, the scene point."""

    index: int
    box: str
    point: np.ndarray


def first_contact(scene: cKDTree, poses: list[np.ndarray], boxes: tuple[ToolBox, ...],
                  clearance_m: float) -> Contact | None:
    """The first of `poses` (4x4 tool poses, base frame) at which a scene point lies within `clearance_m` of a gripper
    box (a negative clearance: that deep inside it); None when the whole path keeps clear."""
    points = scene.data
    for i, T in enumerate(poses):
        R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
        for box in boxes:
            centre, half = np.array(box.centre), np.array(box.half)
            near = scene.query_ball_point(p + R @ centre, float(np.linalg.norm(half)) + max(clearance_m, 0.0))
            if not near:
                continue
            gap = np.abs((points[near] - p) @ R - centre) - half  # per axis: > 0 outside the box's faces
            distance = np.where(np.all(gap <= 0, axis=1), gap.max(axis=1),  # inside: minus the depth
                                np.linalg.norm(np.maximum(gap, 0.0), axis=1))
            if distance.min() <= clearance_m:
                return Contact(i, box.name, points[near][np.argmin(distance)])
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
