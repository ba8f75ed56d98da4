"""Whether a parallel gripper moving through tool poses keeps clear of the scene the camera saw (pure functions, base
frame, metres).

The gripper is a few boxes in its tool frame (z: approach, y: the fingers' closing direction); the scene is the first
frame's points with the part being opened left out (it moves with the gripper). A pose touches the scene when a
scene point lies within the clearance of one of the boxes (or, for a negative clearance, that deep inside one). The
scene is surfaces, not solids: a path is checked between its poses too, finely enough that a surface the gripper
passes through lies deeper than the clearance inside a box at one of the poses checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation, Slerp

MIN_SWEEP_STEP_M = 0.002  # a path is checked at least this finely (a clearance as deep as the thinnest box)


@dataclass(frozen=True)
class ToolBox:
    """A box of the gripper: `centre` and `half` sizes (m) in the tool frame, and its `name`."""

    name: str
    centre: tuple[float, float, float]
    half: tuple[float, float, float]


def parallel_gripper(opening_m: float, max_opening_m: float) -> tuple[ToolBox, ...]:
    """A parallel gripper opened `opening_m` around a tool frame between its finger pads, as the convex hulls of a
    Franka hand's collision meshes give it (what a simulator and the arm's own collision checks use): fingers 2.1 cm
    wide either side of the opening, 5.4 cm long to 0.7 cm past the tool frame, standing out of the opening 2.6 cm at
    the hand and 1.9 cm at the tip (three steps); the hand behind them, 9.2 cm deep, as wide as the widest opening
    plus 6.4 cm each side (20.8 cm), 6 cm thick in its half nearer the fingers and 6.4 cm in the other; the wrist
    behind the hand is left out (the fingers and hand reach the scene first)."""
    half_open = opening_m / 2
    return (ToolBox("fingertips", (0.0, 0.0, -0.0015), (0.0105, half_open + 0.019, 0.0085)),
            ToolBox("fingers", (0.0, 0.0, -0.0185), (0.0105, half_open + 0.0253, 0.0085)),
            ToolBox("fingers", (0.0, 0.0, -0.037), (0.0105, half_open + 0.0264, 0.01)),
            ToolBox("hand", (0.0, 0.0, -0.062), (0.03, max_opening_m / 2 + 0.064, 0.023)),
            ToolBox("hand", (0.0, 0.0, -0.108), (0.032, max_opening_m / 2 + 0.064, 0.023)))


@dataclass(frozen=True)
class Contact:
    """Where a path would touch the scene: the gripper box and the scene point."""

    box: str
    point: np.ndarray


def first_contact(scene: cKDTree, poses: list[np.ndarray], boxes: tuple[ToolBox, ...],
                  clearance_m: float) -> Contact | None:
    """Where the gripper first touches the scene moving through `poses` (4x4 tool poses, base frame, and the motion
    between them): a scene point within `clearance_m` of a gripper box (a negative clearance: that deep inside it);
    None when the whole path keeps clear."""
    for name, points, distance in _near_points(scene, poses, boxes, clearance_m):
        if distance.min() <= clearance_m:
            return Contact(name, points[np.argmin(distance)])
    return None


def clearance(scene: cKDTree, poses: list[np.ndarray], boxes: tuple[ToolBox, ...], up_to_m: float) -> float:
    """How far the gripper keeps from the scene moving through `poses` (as `first_contact` checks them): the smallest
    distance of a scene point to a gripper box (negative: that deep inside it), `up_to_m` when none lies nearer."""
    nearest = up_to_m
    for _, _, distance in _near_points(scene, poses, boxes, up_to_m):
        nearest = min(nearest, float(distance.min()))
    return nearest


def _near_points(scene: cKDTree, poses: list[np.ndarray], boxes: tuple[ToolBox, ...], clearance_m: float):
    """Per pose along the path (swept finely enough for `clearance_m`) and gripper box: the box's name, the scene
    points within `clearance_m` of its bounding sphere and their distances to the box (negative inside)."""
    points = scene.data
    thinnest = 2 * min(min(box.half) for box in boxes)
    reach = max(float(np.linalg.norm(np.abs(box.centre) + box.half)) for box in boxes)
    for T in swept_poses(poses, max(thinnest - 2 * max(-clearance_m, 0.0), MIN_SWEEP_STEP_M), reach):
        R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
        for box in boxes:
            centre, half = np.array(box.centre), np.array(box.half)
            near = scene.query_ball_point(p + R @ centre, float(np.linalg.norm(half)) + max(clearance_m, 0.0))
            if not near:
                continue
            gap = np.abs((points[near] - p) @ R - centre) - half  # per axis: > 0 outside the box's faces
            yield box.name, points[near], np.where(np.all(gap <= 0, axis=1), gap.max(axis=1),  # inside: minus depth
                                                   np.linalg.norm(np.maximum(gap, 0.0), axis=1))


def swept_poses(poses: list[np.ndarray], step_m: float, reach_m: float) -> list[np.ndarray]:
    """`poses` (4x4) with poses between them, interpolated (position linearly, orientation along the shortest turn),
    so that no point within `reach_m` of the tool frame moves more than `step_m` from one to the next."""
    poses = [np.asarray(T, float) for T in poses]
    swept = poses[:1]
    for A, B in zip(poses[:-1], poses[1:], strict=True):
        turns = Rotation.from_matrix([A[:3, :3], B[:3, :3]])
        moved = np.linalg.norm(B[:3, 3] - A[:3, 3]) + (turns[0].inv() * turns[1]).magnitude() * reach_m
        n = max(1, int(np.ceil(moved / step_m)))
        fractions = np.arange(1, n + 1) / n
        for f, R in zip(fractions, Slerp([0.0, 1.0], turns)(fractions).as_matrix(), strict=True):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, A[:3, 3] + f * (B[:3, 3] - A[:3, 3])
            swept.append(T)
    return swept


def first_behind(poses: list[np.ndarray], boxes: tuple[ToolBox, ...], origin: np.ndarray, normal: np.ndarray,
                 depth_m: float) -> Contact | None:
    """Where the gripper at one of `poses` (4x4 tool poses, base frame) reaches more than `depth_m` behind the plane
    through `origin` with outward unit `normal` (the fronts' plane, which the scene leaves out); None when it keeps in
    front of it. Moving straight between the poses, it reaches deepest at one of them."""
    for T in poses:
        for box in boxes:
            corners = _corners(T, box)
            offset = (corners - origin) @ normal
            if offset.min() < -depth_m:
                return Contact(box.name, corners[np.argmin(offset)])
    return None


def depth_behind(poses: list[np.ndarray], boxes: tuple[ToolBox, ...], origin: np.ndarray, normal: np.ndarray
                 ) -> float:
    """How deep the gripper at `poses` reaches behind the plane of `first_behind` (m; 0 when it keeps in front)."""
    offsets = [float(((_corners(T, box) - origin) @ normal).min()) for T in poses for box in boxes]
    return max(0.0, -min(offsets))


def _corners(T: np.ndarray, box: ToolBox) -> np.ndarray:
    """The 8 corners of `box` with the tool at pose T (4x4), base frame."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    R, p = np.asarray(T, float)[:3, :3], np.asarray(T, float)[:3, 3]
    return p + (np.array(box.centre) + signs * box.half) @ R.T


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


def outside_box(points: np.ndarray, centre: np.ndarray, axes: np.ndarray, half: tuple[float, float, float]
                ) -> np.ndarray:
    """The `points` outside the box at `centre` with unit edge directions the rows of `axes` (3x3) and `half` sizes
    along them: e.g. the scene less a handle that moves with the gripper."""
    d = (np.asarray(points, float).reshape(-1, 3) - centre) @ np.asarray(axes, float).T
    return points[np.any(np.abs(d) > np.asarray(half), axis=1)]
