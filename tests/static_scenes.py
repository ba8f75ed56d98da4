"""Synthetic kitchen runs for the static-scene tests: three identical base units (two drawers each, or a door in the
middle one) against a wall under a countertop, on a floor, seen by a D415-like camera; the middle unit's top drawer
(or its door) opens; an arm-like bar may stand in front. Ray-cast (deploy.synthetic.raycast) with the D415 depth
model; the truth per pixel comes from a second cast with labels by group."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from deploy.geometry.types import Box
from deploy.perception.self_filter import MARGIN_M
from deploy.synthetic.raycast import render
from drivers.camera.base import Frame, Intrinsics, SegLabel
from drivers.camera.depth_noise import DepthNoise

INTRINSICS = Intrinsics.from_fov(640, 480, 65.0)
FRONT_X = 0.65  # the carcasses' front plane (fronts stand 2 cm in front of it), facing the robot (-x)
UNIT_W, BOTTOM, TOP, DEPTH = 0.40, 0.10, 0.86, 0.58
PANEL = 0.018
TARGET_Y = -0.20  # the middle unit's left edge (y)


def look_at(eye, target) -> np.ndarray:
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye
    return T


CAMERA = look_at((0.0, 0.45, 1.55), (FRONT_X, -0.05, 0.55))


def _box(lo, hi, rotation=None) -> Box:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Box((lo + hi) / 2, np.eye(3) if rotation is None else rotation, hi - lo)


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _carcass(y0: float) -> list[Box]:
    x1 = FRONT_X + DEPTH
    return [_box((FRONT_X, y0, BOTTOM), (x1, y0 + PANEL, TOP)), _box((FRONT_X, y0 + UNIT_W - PANEL, BOTTOM),
                                                                     (x1, y0 + UNIT_W, TOP)),
            _box((FRONT_X, y0, BOTTOM), (x1, y0 + UNIT_W, BOTTOM + PANEL)),
            _box((FRONT_X, y0, TOP - PANEL), (x1, y0 + UNIT_W, TOP)),
            _box((x1 - PANEL, y0, BOTTOM), (x1, y0 + UNIT_W, TOP)),
            _box((FRONT_X, y0, 0.48), (x1, y0 + UNIT_W, 0.48 + PANEL))]


def _front(y0: float, z0: float, z1: float, shift: float = 0.0) -> list[Box]:
    """A drawer front 2 cm thick, 3 mm gaps, with a bar handle 3 cm in front of it; `shift` m toward the robot."""
    x = FRONT_X - shift
    zc = z1 - 0.08
    return [_box((x - 0.02, y0 + 0.003, z0 + 0.003), (x, y0 + UNIT_W - 0.003, z1 - 0.003)),
            _box((x - 0.045, y0 + UNIT_W / 2 - 0.08, zc - 0.006), (x - 0.033, y0 + UNIT_W / 2 + 0.08, zc + 0.006))]


def _drawer_box(y0: float, shift: float) -> list[Box]:
    """The target drawer's body behind its front (sides, bottom, back), `shift` m out."""
    x0, x1 = FRONT_X - shift, FRONT_X - shift + 0.50
    ya, yb = y0 + 0.03, y0 + UNIT_W - 0.03
    return [_box((x0, ya, 0.52), (x1, ya + 0.012, 0.80)), _box((x0, yb - 0.012, 0.52), (x1, yb, 0.80)),
            _box((x0, ya, 0.52), (x1, yb, 0.532)), _box((x1 - 0.012, ya, 0.52), (x1, yb, 0.80))]


def _door(y0: float, angle: float) -> list[Box]:
    """The middle unit's door, hinged at its left edge (y0), turned `angle` rad toward the robot, with a vertical bar
    near its free edge."""
    hinge = np.array([FRONT_X - 0.02, y0 + 0.003, 0.0])
    R = _rot_z(angle)
    width = UNIT_W - 0.006
    parts = [((0.01, width / 2, (BOTTOM + TOP) / 2), (0.02, width, TOP - BOTTOM - 0.006)),
             ((-0.039, width - 0.05, (BOTTOM + TOP) / 2 + 0.1), (0.012, 0.012, 0.2))]
    return [Box(hinge + R @ np.asarray(c, float), R, np.asarray(e, float)) for c, e in parts]


@dataclass(frozen=True)
class Groups:
    """The scene's boxes by what they are: the target part, the identical fronts (neighbours' and siblings'), the
    target's own furniture (carcass), the static rest (wall, floor, counter, other carcasses), the arm."""

    part: list[Box]
    fronts: list[Box]
    own: list[Box]
    static: list[Box]
    arm: list[Box]


def scene(kind: str, opening: float, arm: bool = False) -> Groups:
    """The run with the target drawer out by `opening` m (kind "drawer") or the door turned `opening` rad ("door")."""
    static = [_box((FRONT_X + DEPTH, -2.0, 0.0), (FRONT_X + DEPTH + 0.05, 2.0, 2.2)),
              _box((0.0, -2.0, -0.02), (FRONT_X + DEPTH, 2.0, 0.0)),
              _box((FRONT_X - 0.05, -0.62, TOP), (FRONT_X + DEPTH, 0.62, TOP + 0.04)),
              _box((FRONT_X + 0.05, -0.62, 0.0), (FRONT_X + DEPTH, 0.62, BOTTOM))]
    fronts, own = [], _carcass(TARGET_Y)
    for y0 in (-0.60, 0.20):
        static += _carcass(y0)
        fronts += _front(y0, BOTTOM, 0.485) + _front(y0, 0.485, TOP)
    if kind == "drawer":
        part = _front(TARGET_Y, 0.485, TOP, opening) + _drawer_box(TARGET_Y, opening)
        fronts += _front(TARGET_Y, BOTTOM, 0.485)
    else:
        part = _door(TARGET_Y, opening)
    bar = [Box(np.array([0.42, 0.02, 0.72]), _rot_z(0.3), np.array([0.36, 0.08, 0.08]))] if arm else []
    return Groups(part, fronts, own, static, bar)


def truth(groups: Groups) -> dict[str, np.ndarray]:
    """(H, W) masks: part, fronts, furniture (own carcass, part and sibling front), static, arm, by exact casts."""
    first = [(b, SegLabel.OBJECT) for b in groups.part] + [(b, SegLabel.HANDLE) for b in groups.fronts] + \
        [(b, SegLabel.ROBOT) for b in groups.arm] + [(b, SegLabel.BACKGROUND) for b in groups.static + groups.own]
    depth, labels = render(first, INTRINSICS, CAMERA)
    own_fronts = [b for b in groups.fronts if TARGET_Y < b.center[1] < TARGET_Y + UNIT_W]
    mine = set(map(id, groups.part + groups.own + own_fronts))
    second = [(b, SegLabel.OBJECT if id(b) in mine else SegLabel.BACKGROUND)
              for b in groups.part + groups.fronts + groups.arm + groups.static + groups.own]
    _, furniture = render(second, INTRINSICS, CAMERA)
    hit = depth > 0
    return {"part": labels == SegLabel.OBJECT, "fronts": labels == SegLabel.HANDLE, "arm": labels == SegLabel.ROBOT,
            "furniture": hit & (furniture == SegLabel.OBJECT), "static": hit & (labels == SegLabel.BACKGROUND)}


def frame(groups: Groups, seed: int, index: int = 0, noise: DepthNoise | None = None) -> Frame:
    """The D415's frame of the scene (its noise drawn from `seed`), the arm's pixels without depth as the self-filter
    leaves them (its silhouette grown by the self-filter's margin at the arm's distance), the camera's pose known."""
    boxes = [(b, SegLabel.BACKGROUND) for b in groups.part + groups.fronts + groups.own + groups.static] + \
        [(b, SegLabel.ROBOT) for b in groups.arm]
    depth, labels = render(boxes, INTRINSICS, CAMERA)
    noise = DepthNoise.d415() if noise is None else noise
    noisy = noise.apply(depth, INTRINSICS.fx, np.random.default_rng(seed))
    arm = labels == SegLabel.ROBOT
    if arm.any():
        grow = int(np.ceil(MARGIN_M * INTRINSICS.fx / float(np.median(depth[arm]))))
        noisy[cv2.dilate(arm.astype(np.uint8), np.ones((2 * grow + 1, 2 * grow + 1), np.uint8)) > 0] = 0.0
    return Frame(index, index / 5.0, np.zeros((480, 640, 3), np.uint8), noisy, INTRINSICS, CAMERA.copy())
