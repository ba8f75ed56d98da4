"""Randomised scenarios like RGBManip's: a cabinet placed in front of the Panda, a third-person camera,
and the arm's start configuration. Pure values; `SimWorld` builds them in PyBullet.

Robot base frame = world frame: origin at the Panda's base, x forward, z up, metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim_fallback.cabinet_urdf import KINDS, SPLITS, CabinetSpec, Split, random_cabinet

Task = Literal["drawer", "door"]
Condition = Literal["normal", "locked", "stiff"]  # the object's joint: as drawn, held fast, 3x the friction
CONDITIONS: tuple[Condition, ...] = ("normal", "locked", "stiff")

# Robot base to the centre of the cabinet's front face (horizontal) and grip centre above the robot base
# (a pedestal lifts the cabinet), per task. A drawer is pulled toward the robot: its ranges keep a 45 cm
# pull in the Panda's dexterous workspace (nearer or lower handles put joint 2 on its limit before the
# end, farther ones start near full stretch), measured with `well_conditioned_start` over the pull. Doors
# stand where RGBManip (and the paper) place objects, 0.5-0.85 m: nearer, a 70 deg door's free edge sweeps
# through the robot's own column (`SimWorld.sweep_hits_robot_base`; 9 of 100 test doors at 0.4-0.7 m).
CABINET_DISTANCE_M = {"drawer": (0.55, 0.68), "door": (0.5, 0.85)}
HANDLE_HEIGHT_M = {"drawer": (0.72, 0.86), "door": (0.62, 0.78)}
CABINET_BEARING_RAD = 0.4  # the cabinet lies within +-this of the robot's x axis
CABINET_YAW_RAD = 0.2  # the cabinet's front turns up to +-this away from facing the robot
MIN_PEDESTAL_M = (0.01, 0.05)  # RGBManip's base-height range, used when the cabinet is tall enough
# Start: the hand retracted 0.3 m in front of the base at 0.75 m height, approach along +x (the ready
# pose's orientation), clear of any cabinet front; jittered per scenario.
Q_START = np.array([0.0, -1.2523, 0.0, -2.6382, 0.0, 2.9565, 0.7854])
START_JITTER_RAD = 0.05  # std of the start configuration around Q_START


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
    """One episode's set-up: cabinet, its pose on a pedestal, camera placement, arm start (rad) and the joint's
    `condition` ("locked": held fast; "stiff": three times its friction)."""

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

    @classmethod
    def make(
        cls, task: Task, seed: int, split: Split = "train", camera: CameraPlacement | None = None,
        condition: Condition = "normal",
    ) -> Scenario:
        """A random scenario, deterministic from (task, seed, split); `camera` overrides the random one; the
        condition changes the joint only (same cabinet, placement and camera)."""
        if condition not in CONDITIONS:
            raise ValueError(f"unknown object condition {condition!r}: use one of {', '.join(CONDITIONS)}")
        cabinet = random_cabinet(task, seed, split)
        rng = np.random.default_rng([SPLITS.index(split), KINDS.index(task), seed, 1])  # not the cabinet's
        distance = rng.uniform(*CABINET_DISTANCE_M[task])
        bearing = rng.uniform(-CABINET_BEARING_RAD, CABINET_BEARING_RAD)
        yaw = bearing + np.pi + rng.uniform(-CABINET_YAW_RAD, CABINET_YAW_RAD)  # front faces the robot
        handle_height = rng.uniform(*HANDLE_HEIGHT_M[task])
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


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4x4 pose of a camera at `eye` looking at `target`, OpenCV optical axes, image top toward +z."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("look_at: the camera looks straight up or down; move it off the vertical")
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye
    return T
