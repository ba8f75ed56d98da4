"""What a simulated world loads, as pure values: placed furniture (one of them holds the target part), static shapes
(floor, walls, countertops, objects) and their finishes. `SimWorld` builds a `Layout`; scenarios make them.

Poses are (x, y, z, yaw): a furniture frame's origin (sim_fallback/furniture.py) or a static shape's centre, turned
by yaw about z; metres and radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim_fallback.furniture import Finish, Furniture

Pose = tuple[float, float, float, float]


def pose_matrix(pose: Pose) -> np.ndarray:
    """4x4 of an (x, y, z, yaw) pose."""
    x, y, z, yaw = pose
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [x, y, z]
    return T


def moved(pose: Pose, T: np.ndarray) -> Pose:
    """`pose` seen from a frame in which its frame sits at T (T turns about z only)."""
    M = T @ pose_matrix(pose)
    return (float(M[0, 3]), float(M[1, 3]), float(M[2, 3]), float(np.arctan2(M[1, 0], M[0, 0])))


@dataclass(frozen=True)
class Placed:
    """A piece of furniture standing at `pose` (its frame's origin: the footprint centre on its bottom)."""

    furniture: Furniture
    pose: Pose

    @property
    def T(self) -> np.ndarray:
        return pose_matrix(self.pose)

    def footprint(self) -> np.ndarray:
        """Its footprint's corners (4x2, in order)."""
        w, d, _ = self.furniture.size_m
        return _rectangle(self.pose, d, w)

    @property
    def heights(self) -> tuple[float, float]:
        return self.pose[2], self.pose[2] + self.furniture.size_m[2]


@dataclass(frozen=True)
class StaticShape:
    """A fixed box or upright cylinder: `size` its extents (x, y, z; a cylinder's x and y are its diameter), `pose`
    its centre; `name` says what it is ("floor", "wall", "countertop", "object", ...). Drawn with its `finish`, or
    without one in `colour`, painted."""

    name: str
    kind: Literal["box", "cylinder"]
    size: tuple[float, float, float]
    pose: Pose
    finish: Finish | None
    colour: tuple[float, float, float, float] | None = None

    def footprint(self) -> np.ndarray:
        """Its footprint's corners (4x2, in order; a cylinder's bounding square)."""
        return _rectangle(self.pose, self.size[0], self.size[1])

    @property
    def heights(self) -> tuple[float, float]:
        return self.pose[2] - self.size[2] / 2, self.pose[2] + self.size[2] / 2

    @property
    def rgba(self) -> tuple[float, float, float, float]:
        if self.colour is not None or self.finish is None:
            return self.colour or (0.5, 0.5, 0.5, 1.0)
        return (*self.finish.rgb, 1.0)


@dataclass(frozen=True)
class Layout:
    """Everything a world loads but the robot: `furniture` (the target part `part` is in `furniture[target]`) and
    `statics`, merged by the world into one body (the first is its base)."""

    furniture: tuple[Placed, ...]
    statics: tuple[StaticShape, ...]
    target: int
    part: str

    @property
    def target_furniture(self) -> Placed:
        return self.furniture[self.target]

    def moved(self, T: np.ndarray) -> Layout:
        """The layout seen from a frame in which its frame sits at `T` (a turn about z and a shift)."""
        return Layout(tuple(Placed(p.furniture, moved(p.pose, T)) for p in self.furniture),
                      tuple(StaticShape(s.name, s.kind, s.size, moved(s.pose, T), s.finish, s.colour)
                            for s in self.statics), self.target, self.part)


def _rectangle(pose: Pose, length_x: float, length_y: float) -> np.ndarray:
    corners = np.array([[sx * length_x / 2, sy * length_y / 2, 0.0, 1.0]
                        for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))])
    return (corners @ pose_matrix(pose).T)[:, :2]


def inside(point: np.ndarray, corners: np.ndarray) -> bool:
    """Whether a 2-D point lies inside the convex polygon `corners` (Nx2, in order)."""
    sides = [_cross(corners[(k + 1) % len(corners)] - corners[k], point - corners[k]) for k in range(len(corners))]
    return bool(all(s >= 0 for s in sides) or all(s <= 0 for s in sides))


def _cross(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])
