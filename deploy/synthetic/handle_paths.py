"""Handle trajectories like those a person or a robot records while opening furniture, with ground truth.

Each path is the pose of a tracker fixed to the handle (positions in metres, quaternions xyzw, base
frame, z up), sampled unevenly over time. What makes real paths hard is modelled explicitly: a
minimum-jerk pull broken by pauses and sometimes a short push back, tremor (band-limited, 5-12 Hz)
and white sensor noise, the play of the part on its runners or track (a slow wobble of position and
orientation that follows the travel), uneven sampling with dropped samples and gaps, tracking glitches
(gross outliers), and hinges that are not exactly vertical or horizontal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.geometry.types import Axis, JointType

PathKind = Literal["drawer", "door", "flap", "slider"]
PATH_KINDS: tuple[PathKind, ...] = ("drawer", "door", "flap", "slider")


@dataclass(frozen=True)
class HandleObject:
    """One piece of furniture: its true joint axis, the handle's start pose, how far it opens (m or rad)
    and how much play its part has (wobble amplitude in m and deg, wavelength along the travel in m)."""

    name: str
    kind: PathKind
    axis: Axis
    start: np.ndarray
    start_rotation: Rotation
    travel: tuple[float, float]
    wobble_m: float
    wobble_deg: float
    wobble_wavelength_m: float


@dataclass(frozen=True)
class HandlePath:
    """One recorded opening of `obj`: times (N,) s, positions (N,3) m, quaternions (N,4) xyzw or None
    (a tracker that gives positions only), and the joint value reached (m or rad)."""

    obj: HandleObject
    times: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray | None
    opened: float

    @property
    def kind(self) -> PathKind:
        return self.obj.kind


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _tilt(direction: np.ndarray, rng: np.random.Generator, max_deg: float) -> np.ndarray:
    """`direction` turned by up to `max_deg` about a random perpendicular axis."""
    perpendicular = _unit(np.cross(direction, rng.normal(size=3)))
    return Rotation.from_rotvec(perpendicular * np.radians(rng.uniform(0, max_deg))).apply(direction)


def random_object(rng: np.random.Generator, kind: PathKind, name: str) -> HandleObject:
    """A drawer (pulled 15-40 cm), a door on a vertical hinge (30-100 deg, radius 0.3-0.6 m, tilted up to
    2.5 deg), a flap on a horizontal hinge (30-80 deg down, radius 0.2-0.4 m) or a sliding part (moved
    20-50 cm along its front, with a wobbling handle), facing the base origin from 0.5-0.9 m."""
    yaw = rng.uniform(-0.6, 0.6)
    facing = np.array([math.cos(yaw), math.sin(yaw), 0.0])  # from the base toward the furniture
    along = np.cross([0.0, 0.0, 1.0], facing)  # the front's horizontal direction
    start = facing * rng.uniform(0.5, 0.9) + np.array([0.0, 0.0, rng.uniform(0.3, 1.1)])
    grip = Rotation.from_matrix(np.column_stack([along, np.cross(-facing, along), -facing]))
    if kind == "drawer":
        axis = Axis(JointType.PRISMATIC, start, _tilt(-facing, rng, 1.0))
        travel, wobble = (0.15, 0.40), (rng.uniform(0.5, 2.0), rng.uniform(0.2, 1.0), rng.uniform(0.1, 0.3))
    elif kind == "slider":
        axis = Axis(JointType.PRISMATIC, start, _tilt(along * rng.choice([-1, 1]), rng, 1.0))
        travel, wobble = (0.20, 0.50), (rng.uniform(2.0, 5.0), rng.uniform(1.0, 3.5), rng.uniform(0.12, 0.4))
    else:
        radius = rng.uniform(0.3, 0.6) if kind == "door" else rng.uniform(0.2, 0.4)
        if kind == "door":  # hinge at one side of the front; opening turns the handle toward the base
            side = rng.choice([-1.0, 1.0])
            direction = _tilt(np.array([0.0, 0.0, side]), rng, 2.5)
            hinge = start + side * along * radius
            travel = (np.radians(30), np.radians(100))
        else:  # hinge below the handle; the flap turns down toward the base
            direction = _tilt(along, rng, 1.5)
            hinge = start - np.array([0.0, 0.0, radius])
            travel = (np.radians(30), np.radians(80))
        axis = Axis(JointType.REVOLUTE, hinge, _unit(direction))
        wobble = (rng.uniform(0.3, 1.5), rng.uniform(0.2, 0.8), rng.uniform(0.1, 0.3))
    return HandleObject(name, kind, axis, start, grip, travel, wobble[0] * 1e-3, wobble[1], wobble[2])


def _profile(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(times, progress 0..1) at 200 Hz: 1-3 minimum-jerk pulls separated by pauses, sometimes a short
    push back before the last pull."""
    pulls = int(rng.integers(1, 4))
    stops = np.sort(rng.uniform(0.2, 0.9, pulls - 1)).tolist() + [1.0]
    times, progress, t, at = [0.0], [0.0], 0.0, 0.0
    for i, stop in enumerate(stops):
        targets = [stop]
        if i == len(stops) - 1 and i > 0 and rng.random() < 0.3:
            targets = [at - rng.uniform(0.03, 0.1) * at, stop]  # pushed back a little, then on
        for target in targets:
            duration = rng.uniform(0.8, 2.5) * max(abs(target - at), 0.1) ** 0.5
            s = np.linspace(0, 1, max(int(duration * 200), 2))[1:]
            times += (t + s * duration).tolist()
            progress += (at + (target - at) * (10 * s**3 - 15 * s**4 + 6 * s**5)).tolist()
            t, at = t + duration, target
        pause = rng.uniform(0.3, 1.5)
        times.append(t + pause)
        progress.append(at)
        t += pause
    return np.array(times), np.array(progress)


def _sample_times(rng: np.random.Generator, end_s: float) -> np.ndarray:
    """Uneven sampling at 15-100 Hz: +-30 % jitter per interval, 5 % dropped samples, 0-2 gaps of 0.2-0.6 s."""
    rate = rng.choice([15.0, 30.0, 60.0, 100.0])
    steps = rng.uniform(0.7, 1.3, int(end_s * rate * 1.5) + 10) / rate
    times = np.concatenate([[0.0], np.cumsum(steps)])
    times = times[times <= end_s]
    keep = rng.random(len(times)) > 0.05
    for _ in range(int(rng.integers(0, 3))):
        start = rng.uniform(0, end_s)
        keep &= ~((times > start) & (times < start + rng.uniform(0.2, 0.6)))
    keep[[0, -1]] = True
    return times[keep]


def _band_noise(rng: np.random.Generator, times: np.ndarray, dims: int, low_hz: float, high_hz: float) -> np.ndarray:
    """Unit-RMS noise (len(times), dims) made of sinusoids between low_hz and high_hz (tremor)."""
    f = rng.uniform(low_hz, high_hz, (8, dims))
    phase = rng.uniform(0, 2 * np.pi, (8, dims))
    return np.sqrt(2 / 8) * np.sum(np.sin(2 * np.pi * f[None] * times[:, None, None] + phase[None]), axis=1)


def _pose_at(obj: HandleObject, q: np.ndarray) -> tuple[np.ndarray, Rotation]:
    """The handle's positions and orientations at joint values q."""
    axis = obj.axis
    if axis.joint_type is JointType.PRISMATIC:
        return obj.start + np.outer(q, axis.direction), Rotation.from_quat(np.tile(obj.start_rotation.as_quat(),
                                                                                   (len(q), 1)))
    turns = Rotation.from_rotvec(np.outer(q, axis.direction))
    return axis.origin + turns.apply(obj.start - axis.origin), turns * obj.start_rotation


def record_path(obj: HandleObject, rng: np.random.Generator, with_orientation: bool = True) -> HandlePath:
    """One opening of `obj` as a tracker on its handle records it (see the module docstring)."""
    opened = rng.uniform(*obj.travel)
    fine_t, progress = _profile(rng)
    times = _sample_times(rng, float(fine_t[-1]))
    q = opened * np.interp(times, fine_t, progress)
    positions, rotations = _pose_at(obj, q)
    travel_m = q * (1.0 if obj.axis.joint_type is JointType.PRISMATIC else np.linalg.norm(
        np.cross(obj.axis.direction, obj.start - obj.axis.origin)))
    phase = rng.uniform(0, 2 * np.pi, 6)
    sway = np.sin(2 * np.pi * travel_m[:, None] / obj.wobble_wavelength_m + phase[None, :3])
    sway = sway - sway[:1]  # the play grows from the closed position
    normal = np.cross(obj.axis.direction, rng.normal(size=3))
    across = np.column_stack([_unit(normal), _unit(np.cross(obj.axis.direction, normal))])
    if obj.axis.joint_type is JointType.REVOLUTE:
        across = np.column_stack([obj.axis.direction, _unit(np.cross(obj.axis.direction, normal))])
    positions = positions + obj.wobble_m * (sway[:, :2] @ across.T)
    tremor_m, sensor_m = rng.uniform(0.3, 1.5) * 1e-3, rng.uniform(0.1, 0.8) * 1e-3
    positions = positions + tremor_m * _band_noise(rng, times, 3, 5, 12) + rng.normal(0, sensor_m, positions.shape)
    wobble = np.radians(obj.wobble_deg) * np.sin(2 * np.pi * travel_m[:, None] / obj.wobble_wavelength_m
                                                 + phase[None, 3:])
    wobble = wobble - wobble[:1]
    jitter = np.radians(rng.uniform(0.1, 0.8)) * rng.normal(size=(len(times), 3))
    rotations = Rotation.from_rotvec(wobble + jitter) * rotations
    glitches = rng.random(len(times)) < rng.uniform(0.0, 0.03)
    glitches[0] = False
    positions[glitches] += rng.normal(size=(glitches.sum(), 3)) * rng.uniform(0.02, 0.15, (glitches.sum(), 1))
    quaternions = rotations.as_quat() if with_orientation else None
    return HandlePath(obj, times, positions, quaternions, float(opened))


def handle_path_set(seed: int = 0, objects_per_kind: tuple[int, ...] = (4, 4, 2, 2),
                    paths_per_object: int = 5) -> list[HandlePath]:
    """The trajectory benchmark's set: per kind in PATH_KINDS order (drawer, door, flap, slider) that many
    objects, each opened `paths_per_object` times; a third of the paths carry no orientations. The
    default is 60 paths of 12 objects."""
    rng = np.random.default_rng(seed)
    paths = []
    for kind, count in zip(PATH_KINDS, objects_per_kind, strict=True):
        for i in range(count):
            obj = random_object(rng, kind, f"{kind}-{i}")
            paths += [record_path(obj, rng, with_orientation=rng.random() > 1 / 3) for _ in range(paths_per_object)]
    return paths
