"""Screw estimator on synthetic moving-part clouds of drawers and doors seen by a D415-like camera."""

from dataclasses import replace

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from deploy.config import EstimatorConfig
from deploy.geometry.estimators.base import Observation
from deploy.geometry.estimators.screw import (
    ScrewEstimator,
    ScrewGripEstimator,
    held_path,
    open_screw,
    open_screw_grip,
)
from deploy.geometry.estimators.screw_config import ScrewConfig
from deploy.geometry.estimators.screw_fit import (
    FREE_DIRECTION_EVIDENCE,
    circle_centre,
    circle_miss,
    direction_sigma_deg,
    fit_revolute,
    fit_screw_joint,
    free_direction_evidence,
    front_face,
    principal_direction,
)
from deploy.geometry.types import Axis, Box, JointType, NoAxis

# Cabinet frame: x out of the front face, z up. The body box includes the closed fronts.
BODY_LO, BODY_HI = np.array([-0.45, -0.3, 0.0]), np.array([0.02, 0.3, 0.7])
MARGIN_M = 0.01
CAMERA = np.array([0.75, 0.3, 0.85])


def box_faces(lo, hi) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(centre, outward normal, edge u, edge v) of the six faces of an axis-aligned box."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre, extent = (lo + hi) / 2, hi - lo
    faces = []
    for axis in range(3):
        u, v = (np.eye(3)[i] * extent[i] for i in range(3) if i != axis)
        for sign in (-1.0, 1.0):
            normal = sign * np.eye(3)[axis]
            faces.append((centre + normal * extent[axis] / 2, normal, u, v))
    return faces


def sample_faces(faces, rng, spacing_m=0.004) -> tuple[np.ndarray, np.ndarray]:
    points, normals = [], []
    for centre, normal, u, v in faces:
        count = rng.poisson(np.linalg.norm(u) * np.linalg.norm(v) / spacing_m**2)
        ab = rng.uniform(-0.5, 0.5, (count, 2))
        points.append(centre + ab[:, :1] * u + ab[:, 1:] * v)
        normals.append(np.tile(normal, (count, 1)))
    return np.concatenate(points), np.concatenate(normals)


def camera_view(points, normals, rng, noise_m) -> np.ndarray:
    """Surfaces facing the camera, two holes, axial noise growing with distance^2, 0.5 % flying pixels."""
    ray = points - CAMERA
    distance = np.linalg.norm(ray, axis=1)
    keep = np.einsum("ij,ij->i", normals, -ray) > 0.05 * distance
    for _ in range(2):
        keep &= np.linalg.norm(points - points[rng.integers(len(points))], axis=1) > rng.uniform(0.01, 0.025)
    ray = ray[keep] / distance[keep, None]
    noise = rng.normal(scale=noise_m * (distance[keep] / 0.6) ** 2)
    flying = (rng.random(len(ray)) < 0.005) * rng.uniform(-0.05, 0.05, len(ray)) * (noise_m > 0)
    return points[keep] + ray * (noise + flying)[:, None]


def drawer(opening_m):
    """Front panel, tray and handle pulled out by `opening_m` along +x; axis (+x) through the handle.

    The tray's front face is left out: the panel hides it (the camera model does not occlude).
    """
    tray = box_faces([-0.35 + opening_m, -0.19, 0.36], [opening_m, 0.19, 0.5])
    faces = [
        *box_faces([opening_m, -0.2, 0.35], [0.02 + opening_m, 0.2, 0.52]),
        *(face for face in tray if face[1][0] <= 0),
        *box_faces([0.02 + opening_m, -0.06, 0.43], [0.045 + opening_m, 0.06, 0.445]),
    ]
    return faces, (np.array([1.0, 0, 0]), np.array([0, 0, 0.43]))


def door_faces(hinge_left: bool):
    y_handle = 0.22 if hinge_left else -0.22
    return [
        *box_faces([0.0, -0.3, 0.02], [0.02, 0.3, 0.68]),
        *box_faces([0.02, y_handle - 0.008, 0.3], [0.05, y_handle + 0.008, 0.45]),
    ]


def door_motion(angle_rad: float, hinge_left: bool):
    """Rotation and hinge of a door opening by `angle_rad` (the free edge comes toward +x)."""
    hinge = np.array([0.0, -0.3 if hinge_left else 0.3, 0.0])
    direction = np.array([0, 0, -1.0 if hinge_left else 1.0])
    return Rotation.from_rotvec(direction * angle_rad), hinge, direction


def make_window(kind, values, seed=0, pose=None, noise_m=1e-3, hinge_left=True, resample=True):
    """Observations of the moving part over openings (m, drawer) or angles (rad, door), base frame.

    `pose` = (R, t) maps the cabinet frame to the base frame. Returns the window and the true axis
    (direction, point). With resample=False the same surface samples move rigidly (no sensor noise).
    """
    rng = np.random.default_rng(seed)
    rotation, translation = pose if pose is not None else (np.eye(3), np.zeros(3))
    box = Box(rotation @ ((BODY_LO + BODY_HI) / 2) + translation, rotation, BODY_HI - BODY_LO)
    fixed = sample_faces(drawer(0.0)[0] if kind == "drawer" else door_faces(hinge_left), rng)
    window = []
    for k, value in enumerate(values):
        if kind == "drawer":
            faces, (direction, point) = drawer(value)
            points, normals = sample_faces(faces, rng) if resample else (fixed[0] + [value, 0, 0], fixed[1])
        else:
            turn, point, direction = door_motion(value, hinge_left)
            points, normals = sample_faces(door_faces(hinge_left), rng) if resample else fixed
            points, normals = turn.apply(points - point) + point, turn.apply(normals)
        points = camera_view(points, normals, rng, noise_m) if resample else points[
            np.einsum("ij,ij->i", normals, CAMERA - points) > 0]
        outside = ~np.all((points >= BODY_LO - MARGIN_M) & (points <= BODY_HI + MARGIN_M), axis=1)
        window.append(Observation(k, 0.1 * k, points[outside] @ rotation.T + translation, box))
    return window, rotation @ direction, rotation @ point + translation


POSES = {  # cabinet frame -> base frame; the camera moves with the cabinet
    name: (Rotation.from_euler("xyz", angles, degrees=True).as_matrix(), np.array(t))
    for name, angles, t in [
        ("upright", [0, 0, 20], [0.6, -0.1, 0.05]),
        ("tilted", [25, -30, 110], [0.5, 0.2, 0.3]),
        ("on its back", [0, -90, 0], [0.7, 0.0, 0.1]),
    ]
}


def angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def distance_to_line(point, origin, direction) -> float:
    d = np.asarray(point) - origin
    return float(np.linalg.norm(d - (d @ direction) * direction))


DRAWER_10CM = 0.03 + np.linspace(0, 0.1, 10)
DOOR_20DEG = np.radians(5 + np.linspace(0, 20, 10))


@pytest.mark.parametrize("pose", POSES.values(), ids=POSES.keys())
def test_noisy_drawer_is_classified_and_recovered(pose):
    window, direction, _ = make_window("drawer", DRAWER_10CM, seed=1, pose=pose)
    axis = ScrewEstimator().estimate(window)
    assert isinstance(axis, Axis) and axis.joint_type is JointType.PRISMATIC
    assert angle_deg(axis.direction, direction) < 1.5  # sign included: along the opening
    assert np.linalg.norm(axis.origin - window[0].moving.mean(axis=0)) < 0.05  # the keyframe part, at the start
    assert axis.residual_m < 0.003 and 0.3 < axis.confidence <= 1.0


@pytest.mark.parametrize("pose", POSES.values(), ids=POSES.keys())
@pytest.mark.parametrize("hinge_left", [True, False], ids=["hinge-left", "hinge-right"])
def test_noisy_door_is_classified_and_recovered(pose, hinge_left):
    window, direction, hinge = make_window("door", DOOR_20DEG, seed=2, pose=pose, hinge_left=hinge_left)
    axis = ScrewEstimator().estimate(window)
    assert isinstance(axis, Axis) and axis.joint_type is JointType.REVOLUTE
    assert angle_deg(axis.direction, direction) < 2.0  # sign included: opening is a positive rotation
    assert distance_to_line(axis.origin, hinge, direction) < 0.015
    centroid = window[-1].moving.mean(axis=0)
    assert axis.radius_m == pytest.approx(distance_to_line(centroid, hinge, direction), abs=0.015)
    assert axis.residual_m < 0.003 and 0.3 < axis.confidence <= 1.0


@pytest.mark.parametrize("kind, values", [("drawer", DRAWER_10CM), ("door", DOOR_20DEG)])
def test_noise_free_motion_is_recovered_exactly(kind, values):
    window, direction, point = make_window(kind, values, pose=POSES["tilted"], resample=False)
    axis = ScrewEstimator().estimate(window)
    assert angle_deg(axis.direction, direction) < 0.05
    if kind == "door":
        assert axis.joint_type is JointType.REVOLUTE
        assert distance_to_line(axis.origin, point, direction) < 1e-3
    else:
        assert axis.joint_type is JointType.PRISMATIC
    assert axis.residual_m < 5e-4


@pytest.mark.parametrize("kind, values", [("drawer", DRAWER_10CM), ("door", DOOR_20DEG)])
def test_closing_motion_flips_the_direction(kind, values):
    window, direction, _ = make_window(kind, values[::-1], seed=3, pose=POSES["upright"], hinge_left=False)
    axis = ScrewEstimator().estimate(window)
    assert angle_deg(axis.direction, -direction) < 2.0


def test_fast_drawer_and_early_door():
    """2 cm per frame; a door from 0 deg, whose first frames have almost no moving part."""
    window, direction, _ = make_window("drawer", 0.02 + np.linspace(0, 0.2, 10), seed=4, pose=POSES["tilted"])
    assert angle_deg(ScrewEstimator().estimate(window).direction, direction) < 1.5
    angles = np.radians(np.linspace(0, 25, 12))
    window, direction, hinge = make_window("door", angles, seed=5, hinge_left=False)
    assert len(window[0].moving) < 0.05 * len(window[-1].moving)  # noise that left the box
    axis = ScrewEstimator().estimate(window)
    assert axis.joint_type is JointType.REVOLUTE and angle_deg(axis.direction, direction) < 2.0
    assert distance_to_line(axis.origin, hinge, direction) < 0.015 and axis.confidence > 0.3


def test_forced_joint_types():
    window, direction, _ = make_window("door", DOOR_20DEG, seed=6)
    assert ScrewEstimator().estimate(window, JointType.PRISMATIC).joint_type is JointType.PRISMATIC
    window, direction, _ = make_window("drawer", DRAWER_10CM, seed=6)
    forced = ScrewEstimator().estimate(window, JointType.REVOLUTE)
    assert isinstance(forced, NoAxis) and "too straight" in forced.reason


def test_one_registration_per_new_frame():
    window, direction, _ = make_window("door", np.radians(5 + np.linspace(0, 24, 12)), seed=7)
    estimator = ScrewEstimator()
    first = estimator.estimate(window[:10])
    assert estimator.registrations == 9
    second = estimator.estimate(window[1:11])
    assert estimator.registrations == 10
    estimator.estimate(window[1:11])
    assert estimator.registrations == 10
    estimator.estimate(window[2:12])
    assert estimator.registrations == 11
    assert angle_deg(first.direction, direction) < 2.0 and angle_deg(second.direction, direction) < 2.0

    fresh = ScrewEstimator().estimate(window[1:11])
    assert angle_deg(fresh.direction, second.direction) < 1.0


def test_a_reused_frame_index_starts_over():
    door, _, _ = make_window("door", DOOR_20DEG, seed=8)
    drawer_window, direction, _ = make_window("drawer", DRAWER_10CM, seed=8)
    drawer_window = [Observation(o.index + 5, o.t, o.moving, o.body_box) for o in drawer_window]
    estimator = ScrewEstimator()
    estimator.estimate(door)
    axis = estimator.estimate(drawer_window)  # frames 5..14: 5..9 now hold other points
    assert estimator.registrations == 18
    assert axis.joint_type is JointType.PRISMATIC and angle_deg(axis.direction, direction) < 1.5


def test_degenerate_windows_give_no_axis_with_a_reason():
    window, _, _ = make_window("drawer", DRAWER_10CM, seed=9)
    empty = [Observation(o.index, o.t, np.zeros((0, 3)), o.body_box) for o in window]
    sparse = [Observation(o.index, o.t, o.moving[:30], o.body_box) for o in window]
    still, _, _ = make_window("drawer", np.full(8, 0.05) + np.linspace(0, 0.004, 8), seed=9)
    cases = {
        "one frame": ScrewEstimator().estimate(window[:1]),
        "no frames": ScrewEstimator().estimate([]),
        "empty clouds": ScrewEstimator().estimate(empty),
        "too few points": ScrewEstimator().estimate(sparse),
        "no motion": ScrewEstimator().estimate(still),
    }
    for name, result in cases.items():
        assert isinstance(result, NoAxis), name
    assert "too few moving-part points" in cases["empty clouds"].reason
    assert "too few moving-part points" in cases["too few points"].reason
    assert "not enough motion" in cases["no motion"].reason


def test_a_frame_that_does_not_match_fails_registration_and_is_skipped_later():
    window, direction, _ = make_window("drawer", 0.03 + np.linspace(0, 0.12, 12), seed=10)
    elsewhere = np.random.default_rng(0).uniform(1.0, 1.3, (3000, 3))
    window[8] = Observation(8, 0.8, elsewhere, window[0].body_box)
    estimator = ScrewEstimator()
    result = estimator.estimate(window[:9])
    assert isinstance(result, NoAxis) and "registration of frame 8 failed" in result.reason
    axis = estimator.estimate(window[2:11])  # a one-frame glitch is skipped
    assert isinstance(axis, Axis) and angle_deg(axis.direction, direction) < 1.5


def test_nan_rows_are_ignored():
    window, direction, _ = make_window("drawer", DRAWER_10CM, seed=11)
    dirty = []
    for o in window:
        moving = o.moving.copy()
        moving[::50] = np.nan
        dirty.append(Observation(o.index, o.t, moving, o.body_box))
    axis = ScrewEstimator().estimate(dirty)
    assert angle_deg(axis.direction, direction) < 1.5
    assert np.all(np.isfinite(np.r_[axis.origin, axis.direction, axis.confidence, axis.residual_m]))


def test_degenerate_shapes_never_give_nan():
    box = Box(np.zeros(3), np.eye(3), np.full(3, 0.1))
    line = np.outer(np.linspace(0, 0.6, 600), [1.0, 0, 0]) + [0, 0.5, 0]
    plate = np.c_[np.random.default_rng(0).uniform(0, 0.4, (3000, 2)), np.zeros(3000)] + [0.3, 0.3, 0.5]
    for frames in (
        [line + [0.01 * k, 0, 0] for k in range(8)],  # slides along itself: no motion to see
        [line + [0, 0.01 * k, 0] for k in range(8)],
        [plate + [0.01 * k, 0, 0] for k in range(8)],
        [np.full((300, 3), np.inf) for _ in range(8)],
    ):
        for joint in (None, JointType.REVOLUTE):
            window = [Observation(i, 0.1 * i, f, box) for i, f in enumerate(frames)]
            result = ScrewEstimator().estimate(window, joint)
            if isinstance(result, Axis):
                values = np.r_[result.origin, result.direction, result.confidence, result.residual_m]
                assert np.all(np.isfinite(values)) and 0.0 <= result.confidence <= 1.0
            else:
                assert result.reason


def test_a_drawer_from_its_first_centimetre_is_fitted_on_the_large_parts():
    """The first frames hold half the later part: they are registered again onto the newest keyframe
    (not chained through their own small clouds) and left out of the fit."""
    window, direction, _ = make_window("drawer", np.linspace(0, 0.1, 11)[1:], seed=22, pose=POSES["tilted"])
    assert len(window[0].moving) < 0.6 * len(window[-1].moving)
    estimator = ScrewEstimator()
    axis = estimator.estimate(window)
    assert estimator.rekey_registrations > 0
    assert axis.joint_type is JointType.PRISMATIC and angle_deg(axis.direction, direction) < 0.8


def with_gripper(window, values, pose, slip_m=0.0):
    """The window with the gripper holding the handle bar's centre (pose = cabinet -> base); from the
    middle frame on, the grasp has slipped by `slip_m` along the door."""
    rotation, translation = pose
    grip = np.array([0.065, 0.22, 0.375])  # door_faces' handle, hinge left, in the cabinet frame
    observations = []
    for k, (observation, value) in enumerate(zip(window, values, strict=True)):
        turn, hinge, _ = door_motion(value, hinge_left=True)
        held = turn.apply(grip - hinge) + hinge + (slip_m * np.array([0, -1.0, 0]) if k >= len(values) // 2 else 0)
        T = np.eye(4)
        T[:3, 3] = rotation @ held + translation
        observations.append(replace(observation, gripper_pose=T))
    return observations


def test_a_held_handle_pins_the_hinge_and_a_slipping_grasp_is_ignored():
    pose = POSES["tilted"]
    window, direction, hinge = make_window("door", DOOR_20DEG, seed=5, pose=pose, noise_m=3e-3)
    vision = ScrewEstimator().estimate(with_gripper(window, DOOR_20DEG, pose))  # the gripper is not used
    held = ScrewGripEstimator().estimate(with_gripper(window, DOOR_20DEG, pose))
    slipped = ScrewGripEstimator().estimate(with_gripper(window, DOOR_20DEG, pose, slip_m=0.03))
    assert ScrewGripEstimator().estimate(window).origin == pytest.approx(vision.origin)  # no poses: screw
    assert all(isinstance(a, Axis) and a.joint_type is JointType.REVOLUTE for a in (vision, held, slipped))
    assert distance_to_line(held.origin, hinge, direction) < 0.004
    assert distance_to_line(held.origin, hinge, direction) < distance_to_line(vision.origin, hinge, direction)
    np.testing.assert_allclose(slipped.origin, vision.origin, atol=1e-9)


def test_circle_centre_is_exact_on_noise_free_tracks():
    w = np.array([0.0, 0.6, 0.8])
    a = np.array([0.3, -0.2, 0.1])
    turns = Rotation.from_rotvec(np.outer(np.radians([4.0, 9.0, 15.0]), w)).as_matrix()
    rotations = np.concatenate([np.eye(3)[None], turns])
    levers = [np.array([0.2, 0.1, 0.4]), np.array([-0.1, 0.3, 0.0])]
    tracks = [(a + rotations @ lever, sigma) for lever, sigma in zip(levers, (0.003, 0.001), strict=True)]
    centre, misses = circle_centre(w, turns, tracks, anchor=float(w @ a))
    np.testing.assert_allclose(centre, a, atol=1e-9)
    np.testing.assert_allclose(misses, 0.0, atol=1e-9)


def hinged(angles_deg, axis, tilt_toward=None, tilt_deg=0.0):
    """Rotations by `angles_deg` about `axis` (through the origin), about an axis tilted by `tilt_deg` toward
    `tilt_toward` when given (a registration's shared bias), and a handle's path 0.3 m out along x about the true
    axis (the start, then after each turn)."""
    axis = np.asarray(axis, float)
    turned = axis if tilt_toward is None else Rotation.from_rotvec(
        np.radians(tilt_deg) * np.cross(axis, tilt_toward)).apply(axis)
    rotations = Rotation.from_rotvec(np.outer(np.radians(angles_deg), turned)).as_matrix()
    path = Rotation.from_rotvec(np.outer(np.radians(np.concatenate([[0.0], angles_deg])), axis)).apply([0.3, 0, 0])
    return rotations, path


def test_a_held_handles_arc_sets_the_hinge_that_biased_registrations_tilt():
    """Registrations that share a tilt of 8 deg give w 8 deg off; the handle's arc in its plane (1 mm noise) pins
    w: the fused w is within 1.5 deg; a path that misses every circle (a slipped grasp) is left out."""
    angles = np.linspace(3.0, 30.0, 10)
    chord = np.array([-np.sin(np.radians(16.5)), np.cos(np.radians(16.5)), 0.0])  # the arc's mid tangent
    rotations, path = hinged(angles, [0, 0, 1.0], chord, 8.0)
    sample = np.random.default_rng(0).uniform([0.05, -0.1, 0.0], [0.35, 0.1, 0.3], (200, 3))  # not a plate
    moved = np.einsum("kij,mj->kmi", rotations, sample)
    path = path + np.random.default_rng(1).normal(0, 1e-3, path.shape)
    tracks = [(np.vstack([sample.mean(axis=0), moved.mean(axis=1)]), 0.003)]
    alone = fit_revolute(rotations, sample, moved, tracks, 0.005, 0.001)
    fused = fit_revolute(rotations, sample, moved, tracks, 0.005, 0.001, 0.003, (path, 0.001))
    slipped = path + np.where(np.arange(len(path))[:, None] >= 5, [0.0, 0.0, 0.03], 0.0)
    ignored = fit_revolute(rotations, sample, moved, tracks, 0.005, 0.001, 0.003, (slipped, 0.001))
    assert angle_deg(alone.direction, [0, 0, 1]) > 7.0
    assert angle_deg(fused.direction, [0, 0, 1]) < 1.5
    assert angle_deg(fused.direction, [0, 0, 1]) < 2 * fused.sigma_deg  # its sigma covers what it cannot see
    np.testing.assert_allclose(ignored.direction, alone.direction, atol=1e-9)


def test_a_door_with_poor_registrations_is_a_hinge_when_the_gripper_held_its_handle():
    """Registrations 6 deg and 3 cm off at random over a 30 deg opening: alone they read the door as a slide in
    several of 10 draws; with the handle's arc (0.5 mm noise) in the joint-type choice it is a hinge within 2.5 deg
    every time, and a straight handle path with the same registrations is a drawer (prismatic)."""
    angles = np.linspace(3.0, 30.0, 10)
    rotations, arc = hinged(angles, [0, 0, 1.0])
    slide = np.outer(np.concatenate([[0.0], angles]) / 100, [-1.0, 0, 0]) + [0.3, 0, 0]
    config, alone = ScrewConfig(), []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        sample = np.column_stack([rng.uniform(0.05, 0.35, 300), np.zeros(300), rng.uniform(0.0, 0.5, 300)])
        noise = Rotation.from_rotvec(rng.normal(0, np.radians(6.0) / np.sqrt(3), (len(angles), 3))).as_matrix()
        poses = np.tile(np.eye(4), (len(angles), 1, 1))
        poses[:, :3, :3] = noise @ rotations
        poses[:, :3, 3] = rng.normal(0, 0.03 / np.sqrt(3), (len(angles), 3))
        path = arc + rng.normal(0, 5e-4, arc.shape)
        centre = rotations[-1] @ sample.mean(axis=0)
        alone.append(fit_screw_joint(poses, sample, centre, 0.9, None, config).joint_type)
        door = fit_screw_joint(poses, sample, centre, 0.9, None, config, path, path)
        assert door.joint_type is JointType.REVOLUTE and angle_deg(door.direction, [0, 0, 1]) < 2.5, seed
        poses[:, :3, :3] = noise
        poses[:, :3, 3] += slide[1:] - slide[0]
        drawer = fit_screw_joint(poses, sample, sample.mean(axis=0), 0.9, None, config, slide, slide)
        assert drawer.joint_type is JointType.PRISMATIC, seed
    assert alone.count(JointType.PRISMATIC) >= 3


def test_circle_miss_is_zero_on_a_circle_about_the_direction_and_not_on_a_line_or_a_tilt():
    _, arc = hinged(np.linspace(5.0, 40.0, 8), [0, 0, 1.0])
    assert circle_miss(arc, np.array([0, 0, 1.0])) < 1e-9
    assert circle_miss(arc, Rotation.from_rotvec([np.radians(5.0), 0, 0]).apply([0, 0, 1.0])) > 1e-3
    line = np.outer(np.linspace(0, 0.2, 8), [1.0, 0, 0])
    assert circle_miss(line + [[0, 0.001 * (-1) ** k, 0] for k in range(8)], np.array([0, 0, 1.0])) > 1e-4


def test_a_held_drawer_handle_straightens_the_direction_and_a_wobbling_one_is_ignored():
    pose = POSES["upright"]
    rotation, translation = pose
    window, direction, _ = make_window("drawer", DRAWER_10CM, seed=5, pose=pose, noise_m=4e-3)
    rng = np.random.default_rng(0)

    def held(wobble_m):
        observations = []
        for observation, value in zip(window, DRAWER_10CM, strict=True):
            T = np.eye(4)
            grip = np.array([0.0325 + value, 0.0, 0.4375]) + rng.normal(0, 1e-3, 3)
            grip[1] += wobble_m * np.sin(value * 60)
            T[:3, 3] = rotation @ grip + translation
            observations.append(replace(observation, gripper_pose=T))
        return observations

    vision = ScrewEstimator().estimate(window)
    fused = ScrewGripEstimator().estimate(held(0.0))
    wobbling = ScrewGripEstimator().estimate(held(0.03))
    assert all(a.joint_type is JointType.PRISMATIC for a in (vision, fused, wobbling))
    assert angle_deg(vision.direction, direction) > 0.8
    assert angle_deg(fused.direction, direction) < 0.4
    np.testing.assert_allclose(wobbling.direction, vision.direction, atol=1e-9)


def test_the_config_reaches_both_estimators():
    window, _, _ = make_window("drawer", DRAWER_10CM, seed=1)
    strict = ScrewEstimator(ScrewConfig(min_points=100_000)).estimate(window)
    assert isinstance(strict, NoAxis) and "need 100000" in strict.reason
    patient = ScrewGripEstimator(ScrewConfig(min_travel_m=0.5, min_rotation_deg=45.0)).estimate(window)
    assert isinstance(patient, NoAxis) and "of 500 mm" in patient.reason
    assert ScrewEstimator().config == ScrewGripEstimator().config == ScrewConfig()


def test_the_config_rejects_bad_values_unknown_keys_and_changes():
    for bad in ({"voxel_m": 0.0}, {"min_fitness": 1.5}, {"max_source": 0}, {"use_gripper": True}):
        with pytest.raises(ValidationError):
            ScrewConfig(**bad)
    with pytest.raises(ValidationError):
        ScrewConfig().voxel_m = 0.01
    assert all(field.description for field in ScrewConfig.model_fields.values())


def test_the_registry_factories_read_the_screw_section():
    section = ScrewConfig(voxel_m=0.01)
    vision = open_screw("", EstimatorConfig(screw=section))
    assert type(vision) is ScrewEstimator and vision.config is section
    grip = open_screw_grip("", None)
    assert type(grip) is ScrewGripEstimator and grip.config == ScrewConfig()


def tilted_drawer_window(direction, seed=0, noise_m=1e-3):
    """The drawer's surfaces pulled along `direction` (cabinet frame) instead of its front's normal (+x)."""
    rng = np.random.default_rng(seed)
    faces, _ = drawer(0.0)
    box = Box((BODY_LO + BODY_HI) / 2, np.eye(3), BODY_HI - BODY_LO)
    window = []
    for k, value in enumerate(DRAWER_10CM):
        points, normals = sample_faces(faces, rng)
        points = camera_view(points + value * np.asarray(direction), normals, rng, noise_m)
        outside = ~np.all((points >= BODY_LO - MARGIN_M) & (points <= BODY_HI + MARGIN_M), axis=1)
        window.append(Observation(k, 0.1 * k, points[outside], box))
    return window


def test_a_drawer_takes_its_fronts_normal_unless_its_motion_shows_otherwise():
    """The front's normal comes with a sigma (the plane fit's error and the slant the motion cannot resolve)
    that leaves the confidence as it was; a slight slant, reported as the front's normal, stays within 2 sigma."""
    straight = ScrewEstimator().estimate(tilted_drawer_window([1.0, 0.0, 0.0]), JointType.PRISMATIC)
    assert angle_deg(straight.direction, [1, 0, 0]) < 0.5 and 0.5 < straight.direction_sigma_deg < 3.0
    assert straight.confidence > 0.9  # 1 / (1 + (sigma / 3 deg)^2) would have taken it to 0.75
    slight = np.array([1.0, np.tan(np.radians(2)), 0.0])
    axis = ScrewEstimator().estimate(tilted_drawer_window(slight), JointType.PRISMATIC)
    assert angle_deg(axis.direction, [1, 0, 0]) < 0.5
    assert angle_deg(axis.direction, slight) < 2 * axis.direction_sigma_deg
    slanted = np.array([1.0, np.tan(np.radians(12)), 0.0])  # runners 12 deg off the front's normal
    axis = ScrewEstimator().estimate(tilted_drawer_window(slanted), JointType.PRISMATIC)
    assert angle_deg(axis.direction, slanted) < 1.5 and axis.direction_sigma_deg < 2.0


def test_front_normal_is_the_plane_of_the_faces_turned_toward_the_motion():
    """The visible faces of an open drawer: the front, the handle 2.5 cm before it and the tray's back
    panel 35 cm behind it face the same way; the front is the largest."""
    rng = np.random.default_rng(0)
    faces, _ = drawer(0.3)
    points, normals = sample_faces(faces, rng)
    visible = np.einsum("ij,ij->i", normals, CAMERA - points) > 0
    points, normals = points[visible], normals[visible]
    noisy = normals + rng.normal(0, 0.1, normals.shape)  # local normals of a noisy cloud scatter
    noisy /= np.linalg.norm(noisy, axis=1, keepdims=True)
    front, sigma = front_face(points + rng.normal(0, 5e-4, points.shape), noisy, np.array([1.0, 0.15, 0.05]))
    assert angle_deg(front, [1, 0, 0]) < 0.3 and 0 < sigma < 0.3
    assert front_face(points[:20], normals[:20], np.array([1.0, 0, 0])) is None
    assert front_face(points, normals, np.array([0.0, 0.0, 1.0]))[0] @ [0, 0, 1] > 0.99  # the tray's bottom


def test_free_direction_evidence_grows_with_a_real_slant():
    s = np.linspace(0, 0.1, 10)[:, None]
    rng = np.random.default_rng(1)
    for slant_deg, expect_free in ((0.0, False), (10.0, True)):
        d = np.array([np.cos(np.radians(slant_deg)), np.sin(np.radians(slant_deg)), 0.0])
        track = s * d + rng.normal(0, 1e-3, (10, 3))
        free = np.linalg.svd(track - track.mean(axis=0))[2][0]
        evidence, sigma = free_direction_evidence([(track, 3e-3)], free, np.array([1.0, 0, 0]))
        assert (evidence > FREE_DIRECTION_EVIDENCE) is expect_free and 0 < sigma < 2.0


def test_a_rekey_undoes_a_slide_along_the_drawer_front():
    """Frames registered onto a small keyframe (the first centimetre of a front) can slide along the
    flat front, here 0.5 of the opening sideways, which point-to-plane ICP onto the new keyframe cannot
    undo from there; starting from the next newer frame's new motion it can."""
    window, direction, _ = make_window("drawer", DRAWER_10CM, seed=1, pose=POSES["upright"])
    estimator = ScrewEstimator()
    estimator.estimate(window[:-1])
    keyframe = estimator._keyframe.index
    sideways = POSES["upright"][0] @ [0.0, 1.0, 0.0]
    for j, registration in estimator._motions.items():
        registration.motion[:3, 3] += 0.5 * (DRAWER_10CM[j] - DRAWER_10CM[keyframe]) * sideways
    estimator._rekey(max(estimator._motions), estimator._clouds)
    axis = estimator.estimate(window[:-1])
    assert angle_deg(axis.direction, direction) < 0.5


def _coverage_of_line_sigma(noise_m: float, drift_m: float, trials: int = 300) -> tuple[float, float]:
    """(share of trials whose direction error is within 2 reported sigmas, median sigma in deg) of
    `direction_sigma_deg` on a 10 cm line of 11 centroid positions (3 mm nominal noise) and a gripper path
    (1 mm nominal), with white noise `noise_m` on both and a sideways drift of `drift_m` over the path."""
    rng = np.random.default_rng(11)
    within, sigmas = [], []
    for _ in range(trials):
        d = Rotation.random(random_state=rng).apply([1.0, 0.0, 0.0])
        side = np.cross(d, rng.normal(size=3))
        side /= np.linalg.norm(side)
        s = np.linspace(0.0, 0.1, 11)[:, None]
        part = s * d + rng.normal(0.0, noise_m, (11, 3))
        grip = s * d + rng.normal(0.0, noise_m, (11, 3)) + (s / 0.1) ** 2 * drift_m * side
        tracks = [(part, 0.003), (grip, 0.001)]
        fitted = principal_direction(tracks)
        sigma = direction_sigma_deg(tracks, fitted)
        within.append(angle_deg(fitted, d) <= 2 * sigma)
        sigmas.append(sigma)
    return float(np.mean(within)), float(np.median(sigmas))


@pytest.mark.parametrize(("noise_m", "drift_m"), [(0.001, 0.0), (0.0003, 0.0), (0.001, 0.002)])
def test_a_drawers_direction_sigma_covers_its_error_95_percent_of_the_time(noise_m, drift_m):
    """The sigma reported for a direction the motion gives (screw-grip's drawers) is what the tracks show: the
    2-sigma interval covers 90-99 % of the errors, whether the noise is the nominal one, smaller, or drifts."""
    share, _ = _coverage_of_line_sigma(noise_m, drift_m)
    assert 0.90 <= share <= 0.99


def test_exact_positions_give_a_small_sigma():
    """A path without noise (a simulator's forward kinematics) says so: no floor from the nominal noise."""
    _, sigma = _coverage_of_line_sigma(0.0, 0.0, trials=5)
    assert sigma < 0.02


def test_a_hinge_reports_a_direction_sigma_that_covers_its_error():
    within = []
    for seed in range(12):
        window, direction, _ = make_window("door", DOOR_20DEG, seed=seed, pose=POSES["upright"])
        axis = ScrewEstimator().estimate(window, JointType.REVOLUTE)
        assert isinstance(axis, Axis) and axis.direction_sigma_deg is not None and axis.direction_sigma_deg > 0
        within.append(angle_deg(axis.direction, direction) <= 2 * axis.direction_sigma_deg)
    assert np.mean(within) >= 0.75


def test_held_path_keeps_the_hold_across_windows_and_restarts_after_a_release():
    T = [np.eye(4) for _ in range(6)]
    for k, pose in enumerate(T):
        pose[:3, 3] = [0.1 * k, 0.0, 0.0]
    box = Box(np.zeros(3), np.eye(3), np.ones(3))
    frames = [Observation(k, 0.1 * k, np.zeros((0, 3)), box, T[k]) for k in range(6)]
    held = held_path({}, frames[0:3])
    held = held_path(held, frames[2:5])  # the window slid past frames 0 and 1: they stay in the hold
    assert sorted(held) == [0, 1, 2, 3, 4]
    np.testing.assert_allclose(held[1], [0.1, 0.0, 0.0])
    released = held_path(held, [frames[3], replace(frames[4], gripper_pose=None), frames[5]])
    assert sorted(released) == [5]  # let go at frame 4: a re-grasp holds the handle elsewhere


def test_the_gripper_path_fitted_is_the_whole_hold_not_only_the_window(monkeypatch):
    """A door held from the first frame, seen through a sliding window of 4 frames: the hinge is fitted to the
    gripper's positions over every frame held so far (a window's short arc barely shows the hinge's tilt)."""
    import deploy.geometry.estimators.screw as screw

    angles = np.radians(np.linspace(0.0, 30.0, 10))
    pose = POSES["upright"]
    window, _, _ = make_window("door", angles, seed=2, pose=pose)
    held = with_gripper(window, angles, pose)
    lengths = []
    real = screw.fit_screw_joint

    def spy(*args):
        lengths.append(None if args[7] is None else len(args[7]))
        return real(*args)

    monkeypatch.setattr(screw, "fit_screw_joint", spy)
    estimator = ScrewGripEstimator()
    for end in range(2, len(held) + 1):
        estimator.estimate(held[max(0, end - 4):end], JointType.REVOLUTE)
    assert lengths and lengths[-1] == len(held)
