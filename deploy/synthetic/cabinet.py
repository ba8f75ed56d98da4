"""Procedural articulated cabinets made of boxes: a body and one drawer or door with a handle.

Cabinet frame: origin at the bottom centre of the front face, x = outward front normal, z up,
y = z x x (to the right of a viewer facing the front). The cabinet sits at `position` (base frame)
turned by `yaw_rad` about z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from deploy.geometry.types import Axis, Box, JointType
from drivers.camera.base import SegLabel

Kind = Literal["drawer", "door"]
_GAP_M = 0.003
_DRAWER_PANEL_M = 0.012


def _pose(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


def _rot_z(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _box(T: np.ndarray, center: tuple[float, float, float], extent: tuple[float, float, float]) -> Box:
    """A box given in the frame `T` (4x4 pose in the base frame)."""
    return Box(T[:3, :3] @ np.asarray(center, float) + T[:3, 3], T[:3, :3].copy(), np.asarray(extent, float))


@dataclass(frozen=True)
class SyntheticCabinet:
    """A cabinet with one drawer (prismatic, opens along the front normal) or one door (revolute about
    a vertical hinge at its left or right edge). Sizes in metres; q in metres or radians, 0 = closed.

    drawer_height_m: height of the drawer front (at the top of the opening; a fixed panel closes the
    rest). The handle is a bar of `handle_length_m` x `handle_bar_m`, its axis `handle_standoff_m`
    in front of the moving part, vertical or horizontal.
    """

    kind: Kind
    width_m: float = 0.5
    height_m: float = 0.6
    depth_m: float = 0.4
    position: tuple[float, float, float] = (0.75, 0.0, 0.0)
    yaw_rad: float = math.pi
    hinge_right: bool = True
    drawer_height_m: float = 0.2
    handle_length_m: float = 0.12
    handle_standoff_m: float = 0.035
    handle_bar_m: float = 0.014
    handle_vertical: bool = False
    panel_m: float = 0.018

    def __post_init__(self) -> None:
        if self.kind not in ("drawer", "door"):
            raise ValueError(f"SyntheticCabinet kind must be 'drawer' or 'door', got {self.kind!r}")
        t = self.panel_m
        if min(self.width_m, self.height_m, self.depth_m) <= 4 * t or t <= 0:
            raise ValueError(f"cabinet {self.width_m}x{self.height_m}x{self.depth_m} m is too small")
        if self.kind == "drawer" and not 0.05 <= self.drawer_height_m <= self.height_m - 2 * t:
            raise ValueError(f"drawer_height_m {self.drawer_height_m} must fit in the {self.height_m} m body")
        if not 0 < self.handle_bar_m < self.handle_standoff_m or self.handle_length_m <= 0:
            raise ValueError("handle needs 0 < handle_bar_m < handle_standoff_m and a positive length")

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        kind: Kind,
        distance_m: tuple[float, float] = (0.6, 0.9),
    ) -> SyntheticCabinet:
        """Width 0.3-0.8 m, height 0.3-0.9, depth 0.3-0.5, on the floor or a 0.3-0.6 m table,
        `distance_m` in front of the base origin (bearing +-0.4 rad), facing it (yaw +-0.2 rad)."""
        t = cls.panel_m
        width, height, depth = rng.uniform(0.3, 0.8), rng.uniform(0.3, 0.9), rng.uniform(0.3, 0.5)
        vertical = kind == "door" and bool(rng.random() < 0.5)
        drawer_height = min(rng.uniform(0.12, 0.3), height - 2 * t - 2 * _GAP_M)
        front_width = width - 2 * t if kind == "drawer" else width
        room = (height - 0.1) if vertical else (front_width - 0.1 if kind == "door" else front_width - 0.06)
        bearing, distance = rng.uniform(-0.4, 0.4), rng.uniform(*distance_m)
        elevation = 0.0 if rng.random() < 0.5 else rng.uniform(0.3, 0.6)
        return cls(
            kind=kind,
            width_m=width,
            height_m=height,
            depth_m=depth,
            position=(distance * math.cos(bearing), distance * math.sin(bearing), elevation),
            yaw_rad=math.pi + bearing + rng.uniform(-0.2, 0.2),
            hinge_right=bool(rng.random() < 0.5),
            drawer_height_m=drawer_height,
            handle_length_m=min(rng.uniform(0.06, 0.2), room),
            handle_standoff_m=rng.uniform(0.025, 0.045),
            handle_bar_m=rng.uniform(0.01, 0.02),
            handle_vertical=vertical,
        )

    @property
    def joint_type(self) -> JointType:
        return JointType.PRISMATIC if self.kind == "drawer" else JointType.REVOLUTE

    @property
    def T_base_cabinet(self) -> np.ndarray:
        """4x4 pose of the cabinet frame in the base frame."""
        return _pose(_rot_z(self.yaw_rad), np.asarray(self.position, float))

    @property
    def _hinge_sign(self) -> float:
        """+1: hinge on the right (+y), opening turns about +z; -1: left hinge, about -z."""
        return 1.0 if self.hinge_right else -1.0

    def _T_cabinet_moving(self, q: float) -> np.ndarray:
        """Pose of the moving part's frame (= cabinet frame at q = 0) in the cabinet frame."""
        if self.kind == "drawer":
            return _pose(np.eye(3), np.array([q, 0.0, 0.0]))
        hinge = np.array([0.0, self._hinge_sign * self.width_m / 2, 0.0])
        R = _rot_z(self._hinge_sign * q)
        return _pose(R, hinge - R @ hinge)

    def _drawer_span_z(self) -> tuple[float, float]:
        top = self.height_m - self.panel_m - _GAP_M
        return top - self.drawer_height_m, top

    def true_axis(self) -> Axis:
        """The joint axis in the base frame; opening is positive q (translation or right-handed turn)."""
        T = self.T_base_cabinet
        if self.kind == "drawer":
            z_lo, z_hi = self._drawer_span_z()
            origin = T[:3, :3] @ np.array([0.0, 0.0, (z_lo + z_hi) / 2]) + T[:3, 3]
            return Axis(JointType.PRISMATIC, origin, T[:3, 0].copy())
        origin = T[:3, :3] @ np.array([0.0, self._hinge_sign * self.width_m / 2, 0.0]) + T[:3, 3]
        return Axis(JointType.REVOLUTE, origin, np.array([0.0, 0.0, self._hinge_sign]))

    def body_parts(self) -> list[tuple[Box, SegLabel]]:
        """The fixed body: back, sides, top, bottom (and, for a drawer, the panel below it)."""
        T, t = self.T_base_cabinet, self.panel_m
        W, H, D = self.width_m, self.height_m, self.depth_m
        boxes = [
            _box(T, (-D + t / 2, 0.0, H / 2), (t, W, H)),
            _box(T, (-D / 2, -W / 2 + t / 2, H / 2), (D, t, H)),
            _box(T, (-D / 2, W / 2 - t / 2, H / 2), (D, t, H)),
            _box(T, (-D / 2, 0.0, t / 2), (D, W - 2 * t, t)),
            _box(T, (-D / 2, 0.0, H - t / 2), (D, W - 2 * t, t)),
        ]
        if self.kind == "drawer":
            z_lo, _ = self._drawer_span_z()
            below = z_lo - _GAP_M - t
            if below > 0.01:
                boxes.append(_box(T, (-t / 2, 0.0, t + below / 2), (t, W - 2 * t, below)))
        return [(box, SegLabel.OBJECT) for box in boxes]

    def moving_parts(self, q: float) -> list[tuple[Box, SegLabel]]:
        """The drawer (front, sides, bottom, back) or the door panel, plus the handle, at joint value q."""
        T = self.T_base_cabinet @ self._T_cabinet_moving(q)
        t, W, H = self.panel_m, self.width_m, self.height_m
        if self.kind == "door":
            panels = [_box(T, (t / 2, 0.0, H / 2), (t, W - 2 * _GAP_M, H - 2 * _GAP_M))]
        else:
            z_lo, z_hi = self._drawer_span_z()
            p = _DRAWER_PANEL_M
            inner_w = W - 2 * t - 2 * _GAP_M
            length = self.depth_m - 2 * t - 0.01
            side_h = self.drawer_height_m - 0.03
            x_mid = -t - length / 2
            z_side = z_lo + 0.01 + side_h / 2
            panels = [
                _box(T, (-t / 2, 0.0, (z_lo + z_hi) / 2), (t, inner_w, self.drawer_height_m)),
                _box(T, (x_mid, -inner_w / 2 + p / 2, z_side), (length, p, side_h)),
                _box(T, (x_mid, inner_w / 2 - p / 2, z_side), (length, p, side_h)),
                _box(T, (x_mid, 0.0, z_lo + 0.01 + p / 2), (length, inner_w, p)),
                _box(T, (-t - length + p / 2, 0.0, z_side), (p, inner_w, side_h)),
            ]
        handle = self._handle(T @ self._T_moving_handle())
        return [(box, SegLabel.OBJECT) for box in panels] + [(box, SegLabel.HANDLE) for box in handle]

    def parts(self, q: float) -> list[tuple[Box, SegLabel]]:
        """Every box of the cabinet at joint value q, in the base frame."""
        return self.body_parts() + self.moving_parts(q)

    def _T_moving_handle(self) -> np.ndarray:
        """The grasp frame in the moving part's frame: origin on the bar's centre, z = approach
        (into the front), x along the bar, y = z x x (the fingers' closing direction)."""
        if self.kind == "drawer":
            z_lo, z_hi = self._drawer_span_z()
            center = np.array([self.handle_standoff_m, 0.0, (z_lo + z_hi) / 2])
        else:
            inset = 0.04 + (self.handle_bar_m / 2 if self.handle_vertical else self.handle_length_m / 2)
            y = -self._hinge_sign * (self.width_m / 2 - inset)
            center = np.array([self.panel_m + self.handle_standoff_m, y, self.height_m / 2])
        x = np.array([0.0, 0.0, 1.0]) if self.handle_vertical else np.array([0.0, 1.0, 0.0])
        z = np.array([-1.0, 0.0, 0.0])
        return _pose(np.column_stack([x, np.cross(z, x), z]), center)

    def _handle(self, T_grasp: np.ndarray) -> list[Box]:
        """The bar and its two standoffs, built in the grasp frame."""
        length, bar, standoff = self.handle_length_m, self.handle_bar_m, self.handle_standoff_m
        post = standoff - bar / 2
        ends = length / 2 - bar / 2
        boxes = [_box(T_grasp, (0.0, 0.0, 0.0), (length, bar, bar))]
        for end in (-ends, ends):
            boxes.append(_box(T_grasp, (end, 0.0, bar / 2 + post / 2), (bar, bar, post)))
        return boxes

    def handle_pose(self, q: float) -> np.ndarray:
        """4x4 grasp frame of the handle at joint value q in the base frame (see `_T_moving_handle`)."""
        return self.T_base_cabinet @ self._T_cabinet_moving(q) @ self._T_moving_handle()
