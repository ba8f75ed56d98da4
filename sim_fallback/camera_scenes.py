"""Scenes for measuring the simulated camera: static surroundings of a kitchen around a world's cabinet (for
`bench sim`'s per-frame cost) and plain walls facing a camera (for the depth models' fill rate and error).

Everything here is visual only (no collision shapes): it changes what the camera sees, not the physics.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

from sim_fallback.furniture import Finish
from sim_fallback.world import SimWorld

UNITS_EACH_SIDE = 3
COUNTER_OVERHANG_M, COUNTER_THICKNESS_M = 0.03, 0.03
WALL_GAP_M = 0.02  # between the backs of the units and the wall
FRONT_GAP_M, FRONT_THICKNESS_M = 0.003, 0.018
HANDLE = (0.012, 0.12, 0.035)  # bar thickness, length, standoff (m)


def box(client: int, half: tuple[float, float, float], centre: np.ndarray, yaw: float,
        rgba: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)) -> int:
    """A static, visual-only box (half extents in its own frame, turned `yaw` about z) : its body id."""
    shape = pb.createVisualShape(pb.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=client)
    quat = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
    return pb.createMultiBody(0.0, -1, shape, [float(v) for v in centre], quat, physicsClientId=client)


def add_kitchen(world: SimWorld, seed: int = 0) -> list[int]:
    """Surround the world's cabinet with a kitchen of static boxes: a floor, a wall behind, a run of units either
    side (touching it, each with a column of one to three fronts and their bar handles), a countertop with an
    overhang over the run; their finishes go into `world.finishes`. Returns the new bodies."""
    rng = np.random.default_rng([seed, 3])
    sc, c = world.scenario, world.client
    spec, T = sc.cabinet, sc.T_base_cabinet
    yaw = sc.cabinet_yaw
    R = T[:3, :3]

    def at(x: float, y: float, z: float) -> np.ndarray:  # a point of the cabinet frame (z from the floor)
        return R @ [x, y, z - sc.pedestal_height_m] + T[:3, 3]

    carcass = Finish(str(rng.choice(["laminate", "wood", "painted"])), tuple(rng.uniform(0.3, 0.8, 3)), 0.15,
                     int(rng.integers(1000)))
    metal = Finish("metal", (0.55, 0.55, 0.57), 0.6, int(rng.integers(1000)))
    height = spec.height_m + sc.pedestal_height_m
    bodies = [box(c, (2.5, 2.5, 0.005), np.array([0.6, 0.0, -0.005]), 0.0)]
    world.finishes[(bodies[-1], -1)] = Finish("wood", (0.45, 0.33, 0.22), 0.2, int(rng.integers(1000)))
    back = -spec.depth_m / 2 - WALL_GAP_M - 0.05
    bodies.append(box(c, (0.05, 2.0, 1.3), at(back, 0.0, 1.3), yaw))
    world.finishes[(bodies[-1], -1)] = Finish("painted", (0.85, 0.84, 0.8), 0.05, 0)
    width = spec.width_m
    for side in (-1, 1):
        for k in range(UNITS_EACH_SIDE):
            y = side * width * (k + 1)
            bodies += _unit(world, at, yaw, y, width, spec.depth_m, height, int(rng.integers(1, 4)), carcass, metal)
    run = width * (2 * UNITS_EACH_SIDE + 1)
    top = height + COUNTER_THICKNESS_M / 2
    bodies.append(box(c, (spec.depth_m / 2 + COUNTER_OVERHANG_M, run / 2, COUNTER_THICKNESS_M / 2),
                      at(COUNTER_OVERHANG_M, 0.0, top), yaw))
    world.finishes[(bodies[-1], -1)] = Finish("laminate", (0.2, 0.2, 0.22), 0.3, int(rng.integers(1000)))
    return bodies


def _unit(world: SimWorld, at, yaw: float, y: float, width: float, depth: float, height: float, fronts: int,
          carcass: Finish, metal: Finish) -> list[int]:
    """One unit of the run centred at `y` (cabinet frame): body, `fronts` stacked fronts, a handle on each."""
    c = world.client
    bodies = [box(c, (depth / 2, width / 2, height / 2), at(0.0, y, height / 2), yaw)]
    world.finishes[(bodies[-1], -1)] = carcass
    front_h = (height - 0.1) / fronts  # a plinth below
    thickness, length, standoff = HANDLE
    for k in range(fronts):
        z = 0.1 + front_h * (k + 0.5)
        bodies.append(box(c, (FRONT_THICKNESS_M / 2, width / 2 - FRONT_GAP_M, front_h / 2 - FRONT_GAP_M),
                          at(depth / 2 + FRONT_THICKNESS_M / 2, y, z), yaw))
        world.finishes[(bodies[-1], -1)] = carcass
        handle_z = z + front_h / 2 - 0.06 if fronts > 1 else z + front_h / 2 - 0.12
        bodies.append(box(c, (thickness / 2, length / 2, thickness / 2),
                          at(depth / 2 + FRONT_THICKNESS_M + standoff, y, handle_z), yaw))
        world.finishes[(bodies[-1], -1)] = metal
    return bodies


def look_along_x(height_m: float = 1.0) -> np.ndarray:
    """A camera pose at (0, 0, height) looking along the world's x axis, level."""
    T = np.eye(4)
    T[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    T[:3, 3] = [0.0, 0.0, height_m]
    return T


def wall(client: int, distance_m: float, height_m: float = 1.0, rgba=(0.8, 0.8, 0.8, 1.0)) -> int:
    """A 6 m square wall facing `look_along_x(height_m)` at `distance_m`."""
    return box(client, (0.01, 3.0, 3.0), np.array([distance_m + 0.01, 0.0, height_m]), 0.0, rgba)
