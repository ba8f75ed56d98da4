"""Randomised scenarios like RGBManip's, in two worlds: "kitchen" (the default: sim_fallback/kitchen_scenario.py)
and "box" (`Scenario`: one cabinet on a pedestal in empty space, the ablation). Pure values; `SimWorld` builds
their `layout()` in PyBullet.

Robot base frame = world frame: origin at the Panda's base, x forward, z up, metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from drivers.arm.robots import PANDA_REACH, Reach
from sim_fallback.cabinet_urdf import KINDS, SPLITS, CabinetSpec, Split, cabinet_furniture, random_cabinet
from sim_fallback.errors import SceneError
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.layout import Layout, Placed, StaticShape
from sim_fallback.placement import CABINET_BEARING_RAD, CABINET_YAW_RAD, look_at
from sim_fallback.start import CONDITIONS, Q_START, START_JITTER_RAD, Condition  # noqa: F401
from sim_fallback.worlds import WORLDS

Task = Literal["drawer", "door"]
MIN_PEDESTAL_M = (0.01, 0.05)  # RGBManip's base-height range, used when the cabinet is tall enough
PEDESTAL_RGBA = (0.45, 0.45, 0.47, 1.0)
FLOOR_SIZE_M = 4.0  # the box world's optional floor square
FLOOR_RGBA = (0.62, 0.6, 0.55, 1.0)


@dataclass(frozen=True)
class CameraPlacement:
    """A fixed third-person camera looking at the cabinet's front centre from `distance_m` away,
    `azimuth_rad` around the front normal (positive toward the cabinet's left) and `elevation_rad`
    above the horizontal."""

    distance_m: float = 0.85
    azimuth_rad: float = 0.45
    elevation_rad: float = 0.55


@dataclass(frozen=True)
class Scenario:
    """One episode's set-up in the box world: cabinet, its pose on a pedestal, camera placement, arm start (rad) and
    the joint's `condition` ("locked": held fast; "stiff": three times its friction)."""

    task: Task
    seed: int
    split: Split
    cabinet: CabinetSpec
    cabinet_xy: tuple[float, float]
    cabinet_yaw: float
    pedestal_height_m: float
    camera: CameraPlacement
    q_start: tuple[float, ...]
    condition: Condition = "normal"

    world = "box"

    @property
    def part(self) -> str:
        return self.cabinet.kind

    @classmethod
    def make(
        cls, task: Task, seed: int, split: Split = "train", camera: CameraPlacement | None = None,
        condition: Condition = "normal", reach: Reach = PANDA_REACH,
    ) -> Scenario:
        """A random scenario, deterministic from (task, seed, split), the handle in the arm's `reach` (default: the
        Panda's); `camera` overrides the random one; the condition changes the joint only (same cabinet, placement
        and camera)."""
        if condition not in CONDITIONS:
            raise ValueError(f"unknown object condition {condition!r}: use one of {', '.join(CONDITIONS)}")
        cabinet = random_cabinet(task, seed, split)
        rng = np.random.default_rng([SPLITS.index(split), KINDS.index(task), seed, 1])  # not the cabinet's
        distance = rng.uniform(*reach.distance(task))
        bearing = rng.uniform(-CABINET_BEARING_RAD, CABINET_BEARING_RAD)
        yaw = bearing + np.pi + rng.uniform(-CABINET_YAW_RAD, CABINET_YAW_RAD)  # front faces the robot
        handle_height = rng.uniform(*reach.height(task))
        pedestal = max(handle_height - cabinet.handle_cabinet[2], rng.uniform(*MIN_PEDESTAL_M))
        random_camera = CameraPlacement(
            distance_m=float(rng.uniform(0.65, 1.0)),
            azimuth_rad=float(rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.6)),
            elevation_rad=float(rng.uniform(0.45, 0.75)),
        )
        q = Q_START + rng.normal(0.0, START_JITTER_RAD, Q_START.shape)  # stays well inside the limits
        front = distance * np.array([np.cos(bearing), np.sin(bearing)])
        centre = front - cabinet.depth_m / 2 * np.array([np.cos(yaw), np.sin(yaw)])
        return cls(
            task=task, seed=seed, split=split, cabinet=cabinet,
            cabinet_xy=(float(centre[0]), float(centre[1])),
            cabinet_yaw=float(np.arctan2(np.sin(yaw), np.cos(yaw))), pedestal_height_m=float(pedestal),
            camera=camera or random_camera,
            q_start=tuple(float(v) for v in q), condition=condition,
        )

    @property
    def T_base_cabinet(self) -> np.ndarray:
        """Pose of the cabinet frame (bottom centre of the body, x out of the front) in the base frame."""
        c, s = np.cos(self.cabinet_yaw), np.sin(self.cabinet_yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = [*self.cabinet_xy, self.pedestal_height_m]
        return T

    @property
    def T_base_camera(self) -> np.ndarray:
        """Camera pose in the base frame, OpenCV optical axes (x right, y down, z forward)."""
        spec, T = self.cabinet, self.T_base_cabinet
        target = T[:3, :3] @ [spec.depth_m / 2, 0.0, spec.height_m / 2] + T[:3, 3]
        cam = self.camera
        out = T[:3, :3] @ [np.cos(cam.azimuth_rad), np.sin(cam.azimuth_rad), 0.0]
        ray = np.cos(cam.elevation_rad) * out + [0.0, 0.0, np.sin(cam.elevation_rad)]
        return look_at(target + cam.distance_m * ray, target)

    def build_layout(self, floor: bool = False) -> Layout:
        """The cabinet on its pedestal (and with `floor` a 4 m floor square)."""
        spec, T = self.cabinet, self.T_base_cabinet
        pose = (*self.cabinet_xy, self.pedestal_height_m, self.cabinet_yaw)
        centre = T[:3, :3] @ [0.0, 0.0, -self.pedestal_height_m / 2] + T[:3, 3]
        statics = [StaticShape("pedestal", "box", (spec.depth_m - 0.02, spec.width_m - 0.02, self.pedestal_height_m),
                               (*centre, self.cabinet_yaw), None, PEDESTAL_RGBA)]
        if floor:
            statics.append(StaticShape("floor", "box", (FLOOR_SIZE_M, FLOOR_SIZE_M, 0.01), (0.5, 0.0, -0.005, 0.0),
                                       None, FLOOR_RGBA))
        return Layout((Placed(cabinet_furniture(spec), pose),), tuple(statics), 0, spec.kind)


def make_scenario(world: str, task: Task, seed: int, split: Split = "train", part: str | None = None,
                  target=None, condition: Condition = "normal",
                  reach: Reach = PANDA_REACH, opening: float = 0.0) -> Scenario | KitchenScenario:
    """The scenario of `world` ("kitchen" or "box"), deterministic from its arguments, the target's grip in the arm's
    `reach`. `part` (the user's `--part` text), `target` (a `Furniture` to open) and `opening` (the seed's part opens
    at least this far, m or rad) apply to kitchens; the box world has its one cabinet, which opens farther than any
    task asks. SceneError for an unknown world, or a part the box world's cabinet does not have."""
    if world == "box":
        scenario = Scenario.make(task, seed, split, condition=condition, reach=reach)
        if part not in (None, task, "0"):
            raise SceneError(f"--part {part!r}: the box world's cabinet has one part, its {task} (0): drop --part, or "
                             "use --world kitchen")
        return scenario
    if world == "kitchen":
        return KitchenScenario.make(task, seed, split, part=part, target=target, condition=condition, reach=reach,
                                    opening=opening)
    raise SceneError(f"--world {world!r} is not a world: use one of {', '.join(WORLDS)}")

