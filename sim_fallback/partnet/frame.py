"""Pure geometry of a model's pose: which way its parts open, where its front is, and its pose in the furniture
frame (x out of the front, y left, z up, origin at the footprint's centre on the floor).

PartNet-Mobility models are modelled y up and aligned with their model axes (ShapeNet's alignment), with the
front on any of the four horizontal axes: the front is the horizontal model axis the openable parts open
toward (drawers along their axis, doors where their free edge swings)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def opening_direction(joint_type: str, axis: np.ndarray, origin: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Unit direction a part moves as its joint starts to open: a prismatic joint's `axis`; for a revolute one,
    the motion of the part's `centre` about the hinge line through `origin` along `axis` (all in one frame)."""
    if joint_type == "prismatic":
        return axis / np.linalg.norm(axis)
    motion = np.cross(axis, centre - origin)
    norm = np.linalg.norm(motion)
    return motion / norm if norm > 1e-9 else np.zeros(3)


def swept(points: np.ndarray, joint_type: str, axis: np.ndarray, origin: np.ndarray, upper: float,
          count: int = 12) -> np.ndarray:
    """`points` at `count` values of their joint's range [0, `upper`]: slid along the unit `axis` (prismatic) or
    turned about the line through `origin` along it (revolute), all in one frame; stacked."""
    values = np.linspace(0.0, upper, count)
    if joint_type == "prismatic":
        return np.concatenate([points + v * axis for v in values])
    turns = Rotation.from_rotvec(values[:, None] * axis[None, :])
    return np.concatenate([turn.apply(points - origin) + origin for turn in turns])


def nearest_horizontal_axis(direction: np.ndarray, model_axes: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Of the horizontal model axes (+-columns of `model_axes` perpendicular to `up`), the one closest to
    `direction`."""
    candidates = [s * a for a in model_axes.T if abs(a @ up) < 0.5 for s in (1.0, -1.0)]
    return max(candidates, key=lambda a: float(a @ direction))


def front_direction(directions: list[np.ndarray], model_axes: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The front: the horizontal model axis closest to the mean of the parts' opening `directions` (their
    horizontal components, each counted once)."""
    flat = [d - (d @ up) * up for d in directions]
    flat = [d / np.linalg.norm(d) for d in flat if np.linalg.norm(d) > 1e-6]
    if not flat:
        raise ValueError("no part opens horizontally")
    return nearest_horizontal_axis(np.sum(flat, axis=0), model_axes, up)


def furniture_rotation(front: np.ndarray, up: np.ndarray) -> np.ndarray:
    """3x3 rotation taking vectors of the model's root frame to the furniture frame (x `front`, z `up`)."""
    x = front / np.linalg.norm(front)
    z = up - (up @ x) * x
    z /= np.linalg.norm(z)
    return np.stack([x, np.cross(z, x), z])


def footprint_pose(R: np.ndarray, points: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """The root's 4x4 pose in the furniture frame for a model whose `points` (root frame, model units) span
    the body, scaled by `scale`, and the body's (width, depth, height) in metres."""
    turned = points @ R.T
    lo, hi = turned.min(axis=0), turned.max(axis=0)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -scale * np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    depth, width, height = scale * (hi - lo)
    return T, np.array([width, depth, height])
