"""Where the robot and the camera stand in front of a target part (pure geometry, metres, radians, z up).

The robot parks the way RGBManip places its objects (the paper's benchmark) and a user parks a robot in front of
what it must open: the target part's grip in the arm's `Reach` (drivers/arm/robots.py: for the Panda 0.5-0.85 m from
the robot base, drawers 0.55-0.68 m), within +-0.4 rad of its forward axis, the front turned up to +-0.2 rad away
from facing it.

Reach rule: the robot base stands BASE_HEIGHT_M above the floor (from on the floor up to a mobile base with a lift),
at a height drawn so that the grip lies in the arm's reach height band above the robot base (for the Panda where the
box world's handles are: the heights at which it pulls a drawer 45 cm and swings a door without meeting its joint
limits). A part whose grip no base height brings into that band is out of reach.

The camera stands as a user mounts it: on a tripod beside the robot, or on a mast on the robot's base looking over
the arm; aimed near the part, not at its centre, with the part's front (closed) and its grip (opened) inside the
camera's field of view and its line of sight clear of furniture and of the arm at its start.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from drivers.arm.robots import Reach
from sim_fallback.layout import inside

CABINET_BEARING_RAD = 0.4  # the target lies within +-this of the robot's x axis
CABINET_YAW_RAD = 0.2  # its front turns up to +-this away from facing the robot
BASE_HEIGHT_M = (0.0, 1.0)  # the robot base above the floor
STAND_HALF_M = 0.22  # the robot's stand (or mobile base): a square this half-width under the robot base
CLEARANCE_M = 0.05  # the stand keeps this far from furniture
TRIPOD_HEIGHT_M = (1.2, 1.8)  # a tripod's head above the floor
FOV_DEG = (65.0, 51.0)  # the simulated D415's field of view at 640x480 (horizontal, vertical)
VIEW_MARGIN = 0.05  # what must be in view stays this share of the half field inside its edges
MIN_RANGE_M = 0.55  # the camera stays this far from the part (a D415 sees from about 0.45 m)
MAX_VIEW_ANGLE_DEG = 60.0  # the camera sees the front at most this far from straight on
AIM_OFFSET_M = (0.15, 0.10)  # the aim point strays up to this far from the part's centre (sideways, up or down)
SIGHT_END_M = 0.03  # the line of sight's end at the part may pass through what holds the part
# what the arm at its start configuration (sim_fallback/start.py) fills, base frame: no line of sight crosses it.
# Its front edge is the Panda's hand at its start, or nearer for an arm parked nearer (`arm_at_start`).
ARM_AT_START = (np.array([[0.45, 0.12], [0.45, -0.12], [-0.15, -0.12], [-0.15, 0.12]]), 0.0, 0.95)
ARM_CLEARANCE_M = 0.05  # the arm at its start stays this far short of the nearest grip its reach allows
CameraKind = Literal["tripod", "base"]


def base_heights(grip_height_m: float, task: str, reach: Reach) -> tuple[float, float] | None:
    """The robot base heights above the floor (lo, hi) that put a grip `grip_height_m` above the floor in `reach`;
    None when there are none."""
    lo = max(BASE_HEIGHT_M[0], grip_height_m - reach.height(task)[1])
    hi = min(BASE_HEIGHT_M[1], grip_height_m - reach.height(task)[0])
    return (lo, hi) if lo <= hi else None


def turn(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def park_robot(grip: np.ndarray, normal: np.ndarray, task: str, obstacles: list[np.ndarray],
               rng: np.random.Generator, reach: Reach, attempts: int = 60) -> np.ndarray:
    """T_base_room: the room (where the target's grip and horizontal front `normal` are given) seen from a robot
    parked in front of the part with the grip at a distance in its `reach`, its stand clear of the `obstacles`
    (footprints, Nx2 in the room frame). The base height is not in it (z unchanged). ValueError when no parking spot
    is found."""
    heading = np.arctan2(normal[1], normal[0])
    for _ in range(attempts):
        distance = rng.uniform(*reach.distance(task))
        bearing = rng.uniform(-CABINET_BEARING_RAD, CABINET_BEARING_RAD)
        yaw = bearing + np.pi + rng.uniform(-CABINET_YAW_RAD, CABINET_YAW_RAD)  # the front's normal, robot frame
        T = turn(yaw - heading)
        T[:2, 3] = distance * np.array([np.cos(bearing), np.sin(bearing)]) - T[:2, :2] @ grip[:2]
        room_from_base = np.linalg.inv(T)
        stand = np.array([[sx * STAND_HALF_M, sy * STAND_HALF_M, 0.0, 1.0]
                          for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))]) @ room_from_base.T
        if all(not overlap(stand[:, :2], o) for o in obstacles):
            return T
    raise ValueError("no room to park the robot in front of the target part: the furniture around it is in the way")


def overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex polygons (Nx2, in order) overlap (separating axis test), with CLEARANCE_M between them
    counting as overlap."""
    for poly in (a, b):
        for k in range(len(poly)):
            edge = poly[(k + 1) % len(poly)] - poly[k]
            axis = np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)
            pa, pb = a @ axis, b @ axis
            if pa.max() + CLEARANCE_M < pb.min() or pb.max() + CLEARANCE_M < pa.min():
                return False
    return True


@dataclass(frozen=True)
class CameraMount:
    """A fixed camera: on a `tripod` beside the robot or on the robot's `base`, at `eye`, aimed at `aim` (base
    frame)."""

    kind: CameraKind
    eye: tuple[float, float, float]
    aim: tuple[float, float, float]

    @property
    def T_base_camera(self) -> np.ndarray:
        return look_at(np.array(self.eye), np.array(self.aim))


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


def in_view(T_base_camera: np.ndarray, points: np.ndarray) -> bool:
    """Whether every point (Nx3, base frame) lies inside the field of view (less VIEW_MARGIN) and beyond MIN_RANGE_M
    * 0.8 (the far part of a front may be nearer than its centre)."""
    local = (np.asarray(points, float) - T_base_camera[:3, 3]) @ T_base_camera[:3, :3]
    z = local[:, 2]
    if np.any(z < 0.8 * MIN_RANGE_M):
        return False
    tan = np.tan(np.radians(FOV_DEG) / 2) * (1 - VIEW_MARGIN)
    return bool(np.all(np.abs(local[:, 0] / z) <= tan[0]) and np.all(np.abs(local[:, 1] / z) <= tan[1]))


Obstacle = tuple[np.ndarray, float, float]  # a footprint (Nx2, convex, in order) and the heights it spans


def place_camera(centre: np.ndarray, grip: np.ndarray, normal: np.ndarray, must_see: np.ndarray, floor_z: float,
                 obstacles: list[Obstacle], rng: np.random.Generator, arm: Obstacle = ARM_AT_START,
                 attempts: int = 80, tripod_m: tuple[float, float] = TRIPOD_HEIGHT_M) -> CameraMount:
    """A camera mount seeing the points `must_see` (base frame) from beside the robot, aimed near `centre` (the
    part's front centre), within MAX_VIEW_ANGLE_DEG of the front's `normal`, its lines of sight to `centre` and to
    the `grip` clear of the `obstacles` (base frame) and of the `arm` at its start; a tripod's head `tripod_m` (low,
    high) above the floor. ValueError when no mount sees it all."""
    first: CameraKind = "tripod" if rng.random() < 0.5 else "base"
    for attempt in range(attempts):
        kind = first if attempt < attempts // 2 else ("base" if first == "tripod" else "tripod")
        side = rng.choice([-1.0, 1.0])
        if kind == "tripod":
            eye = np.array([rng.uniform(-0.8, 0.05), side * rng.uniform(0.35, 0.9), floor_z + rng.uniform(*tripod_m)])
        else:
            eye = np.array([rng.uniform(-0.25, -0.1), side * rng.uniform(0.1, 0.3), rng.uniform(0.95, 1.3)])
        seen_from = (eye - centre) / np.linalg.norm(eye - centre)
        if (np.linalg.norm(centre - eye) < MIN_RANGE_M or seen_from @ normal < np.cos(np.radians(MAX_VIEW_ANGLE_DEG))
                or not all(_clear(eye, p, [*obstacles, arm]) for p in (centre, grip))):
            continue
        forward = (centre - eye) / np.linalg.norm(centre - eye)
        sideways = np.cross(forward, [0.0, 0.0, 1.0])
        sideways /= np.linalg.norm(sideways)
        offset = rng.uniform(-1, 1) * AIM_OFFSET_M[0] * sideways + rng.uniform(-1, 1) * AIM_OFFSET_M[1] * np.array(
            [0.0, 0.0, 1.0])
        for share in (1.0, 0.5, 0.25, 0.0):
            aim = centre + share * offset
            if in_view(look_at(eye, aim), must_see):
                return CameraMount(kind, tuple(float(v) for v in eye), tuple(float(v) for v in aim))  # type: ignore
    raise ValueError("no camera position beside the robot or on its base sees the whole target part: the part is "
                     "too large or too close to the robot")


def arm_at_start(reach: Reach, task: str) -> Obstacle:
    """The volume the arm fills at its start (ARM_AT_START), its front edge drawn back to ARM_CLEARANCE_M short of
    the nearest grip of `reach`: a user parks an arm so that it starts clear of what it is to open."""
    footprint, lo, hi = ARM_AT_START
    front = min(footprint[:, 0].max(), reach.distance(task)[0] - ARM_CLEARANCE_M)
    return np.column_stack([np.minimum(footprint[:, 0], front), footprint[:, 1]]), lo, hi


def _clear(eye: np.ndarray, point: np.ndarray, obstacles: list[Obstacle]) -> bool:
    """The segment from `eye` to `point` (but its last SIGHT_END_M) outside every obstacle."""
    length = np.linalg.norm(point - eye)
    points = eye + np.linspace(0.0, 1.0 - SIGHT_END_M / length, 50)[:, None] * (point - eye)
    for footprint, lo, hi in obstacles:
        for p in points:
            if lo <= p[2] <= hi and inside(p[:2], footprint):
                return False
    return True
