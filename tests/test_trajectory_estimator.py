"""Axis from gripper trajectories: lines, arcs, orientations, outliers, classification, parsing."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.base import Observation
from deploy.geometry.estimators.trajectory import (
    TrajectoryEstimator,
    fit_circle_3d,
    fit_line,
    fit_trajectory,
    parse_trajectory_text,
)
from deploy.geometry.types import Axis, Box, JointType, NoAxis


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions, sign included."""
    return float(np.degrees(np.arccos(np.clip(unit(a) @ unit(b), -1.0, 1.0))))


def distance_to_line(point: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> float:
    d = point - origin
    return float(np.linalg.norm(d - (d @ unit(direction)) * unit(direction)))


def drawer_path(direction, n=20, travel_m=0.1, noise_m=0.0, seed=0, start=(0.5, 0.1, 0.6)):
    """Gripper positions (N,3) along `direction` and a constant orientation (N,4)."""
    rng = np.random.default_rng(seed)
    positions = np.asarray(start) + np.outer(np.linspace(0, travel_m, n), unit(direction))
    quaternions = np.tile(Rotation.from_euler("xyz", [10, 80, 5], degrees=True).as_quat(), (n, 1))
    return positions + rng.normal(scale=noise_m, size=positions.shape), quaternions


def door_path(axis, hinge, arm, arc_deg=20.0, n=20, noise_m=0.0, seed=0):
    """Gripper poses on an arc of `arc_deg` (positive about `axis`) around the hinge line.

    `arm` is the hinge-to-handle vector at the start (its component along the axis is kept).
    The gripper orientation rotates with the door.
    """
    rng = np.random.default_rng(seed)
    turns = Rotation.from_rotvec(np.outer(np.radians(np.linspace(0, arc_deg, n)), unit(axis)))
    positions = np.asarray(hinge) + turns.apply(arm)
    quaternions = (turns * Rotation.from_euler("z", 30, degrees=True)).as_quat()
    return positions + rng.normal(scale=noise_m, size=positions.shape), quaternions


def add_outliers(positions: np.ndarray, fraction: float, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = positions.copy()
    picked = rng.choice(len(out), int(round(fraction * len(out))), replace=False)
    out[picked] += unit(rng.normal(size=(len(picked), 3)).T).T * rng.uniform(0.03, 0.1, (len(picked), 1))
    return out


PRISMATIC_DIRECTIONS = [[1, 0, 0], [0, -1, 0], [0.3, 0.2, -0.9], [0, 0, 1], [-0.5, 0.7, 0.4]]

# (axis, hinge point, hinge-to-handle at the start): vertical hinge on the left / right of the door
# (both opening senses), and tilted axes.
DOORS = {
    "vertical-left-ccw": ([0, 0, 1], [0.6, 0.2, 0.5], [0.0, -0.4, 0.05]),
    "vertical-right-cw": ([0, 0, -1], [0.6, -0.2, 0.5], [0.0, 0.4, 0.05]),
    "tilted": (unit([0.2, -0.3, 0.93]), [0.7, 0.0, 0.4], [0.1, 0.35, 0.0]),
    "horizontal-flap": ([0, 1, 0], [0.6, 0.0, 0.3], [0.0, 0.0, 0.3]),
}


@pytest.mark.parametrize("direction", PRISMATIC_DIRECTIONS)
@pytest.mark.parametrize("with_orientation", [True, False])
def test_noise_free_prismatic_is_recovered_exactly(direction, with_orientation):
    positions, quaternions = drawer_path(direction)
    axis = fit_trajectory(positions, quaternions if with_orientation else None)
    assert isinstance(axis, Axis) and axis.joint_type is JointType.PRISMATIC
    assert angle_deg(axis.direction, direction) < 1e-4
    assert distance_to_line(positions[0], axis.origin, axis.direction) < 1e-8
    assert axis.residual_m < 1e-8 and 0.5 < axis.confidence <= 1.0


def test_prismatic_direction_follows_the_motion():
    positions, _ = drawer_path([0, 1, 0])
    axis = fit_trajectory(positions[::-1], joint=JointType.PRISMATIC)
    assert angle_deg(axis.direction, [0, -1, 0]) < 1e-4


@pytest.mark.parametrize("door", DOORS.values(), ids=DOORS.keys())
@pytest.mark.parametrize("with_orientation", [True, False])
def test_noise_free_revolute_is_recovered_exactly(door, with_orientation):
    axis_direction, hinge, arm = door
    positions, quaternions = door_path(axis_direction, hinge, arm, arc_deg=30)
    axis = fit_trajectory(positions, quaternions if with_orientation else None)
    assert isinstance(axis, Axis) and axis.joint_type is JointType.REVOLUTE
    assert angle_deg(axis.direction, axis_direction) < 1e-3  # sign included: opening is positive
    assert distance_to_line(axis.origin, hinge, axis_direction) < 1e-6
    radius_m = distance_to_line(np.asarray(arm, float), np.zeros(3), axis_direction)
    assert axis.radius_m == pytest.approx(radius_m, abs=1e-6)
    assert axis.residual_m < 1e-6


@pytest.mark.parametrize("door", DOORS.values(), ids=DOORS.keys())
def test_revolute_sign_flips_with_the_sense_of_motion(door):
    axis_direction, hinge, arm = door
    positions, quaternions = door_path(axis_direction, hinge, arm, arc_deg=30)
    for q in (quaternions[::-1], None):
        axis = fit_trajectory(positions[::-1], q, joint=JointType.REVOLUTE)
        assert angle_deg(axis.direction, -np.asarray(axis_direction)) < 1e-3


def test_noisy_short_door_arc_with_orientations():
    """1 mm position noise, 20 deg arc, r = 0.4 m, 0.2 deg orientation noise: axis within 2 deg."""
    angles, offsets = [], []
    for seed in range(10):
        axis_direction, hinge, arm = DOORS["tilted"]
        positions, quaternions = door_path(axis_direction, hinge, unit(arm) * 0.4, 20, 20, 1e-3, seed)
        jitter = Rotation.from_rotvec(np.random.default_rng(seed).normal(scale=np.radians(0.2), size=(20, 3)))
        axis = fit_trajectory(positions, (jitter * Rotation.from_quat(quaternions)).as_quat())
        assert axis.joint_type is JointType.REVOLUTE
        angles.append(angle_deg(axis.direction, axis_direction))
        offsets.append(distance_to_line(axis.origin, hinge, axis_direction))
    assert np.median(angles) < 2.0 and np.median(offsets) < 0.015


def test_noisy_door_arc_from_positions_only():
    """Without orientations the normal comes from the arc's curvature: 1 mm noise on a 60 deg arc."""
    angles = []
    for seed in range(10):
        axis_direction, hinge, arm = DOORS["vertical-left-ccw"]
        positions, _ = door_path(axis_direction, hinge, arm, 60, noise_m=1e-3, seed=seed)
        axis = fit_trajectory(positions)
        assert axis.joint_type is JointType.REVOLUTE
        angles.append(angle_deg(axis.direction, axis_direction))
    assert np.median(angles) < 2.0


def test_noisy_drawer_is_classified_and_recovered():
    for seed in range(10):
        direction = PRISMATIC_DIRECTIONS[seed % len(PRISMATIC_DIRECTIONS)]
        positions, quaternions = drawer_path(direction, noise_m=1e-3, seed=seed)
        for q in (quaternions, None):
            axis = fit_trajectory(positions, q)
            assert axis.joint_type is JointType.PRISMATIC
            assert angle_deg(axis.direction, direction) < 2.0


@pytest.mark.parametrize("with_orientation", [True, False])
def test_ten_percent_gross_outliers(with_orientation):
    positions, quaternions = drawer_path([0.2, -1, 0.1], n=30, noise_m=5e-4)
    axis = fit_trajectory(add_outliers(positions, 0.1), quaternions if with_orientation else None)
    assert axis.joint_type is JointType.PRISMATIC and angle_deg(axis.direction, [0.2, -1, 0.1]) < 1.5
    assert axis.residual_m < 2e-3

    axis_direction, hinge, arm = DOORS["vertical-right-cw"]
    positions, quaternions = door_path(axis_direction, hinge, arm, 45, n=30, noise_m=5e-4)
    axis = fit_trajectory(add_outliers(positions, 0.1), quaternions if with_orientation else None)
    assert axis.joint_type is JointType.REVOLUTE and angle_deg(axis.direction, axis_direction) < 2.0
    assert distance_to_line(axis.origin, hinge, axis_direction) < 0.01
    assert axis.residual_m < 2e-3


def test_fit_line_and_circle_reject_outliers():
    positions, _ = drawer_path([1, 1, 0], n=30)
    origin, direction, rms = fit_line(add_outliers(positions, 0.2))
    assert angle_deg(direction, [1, 1, 0]) < 1e-4 or angle_deg(-direction, [1, 1, 0]) < 1e-4
    assert rms < 1e-9 and distance_to_line(positions[3], origin, direction) < 1e-9

    positions, _ = door_path([0, 0, 1], [0.5, 0, 0.2], [0.3, 0, 0], 90, n=30)
    center, normal, radius, rms = fit_circle_3d(add_outliers(positions, 0.2))
    assert np.linalg.norm(center - [0.5, 0, 0.2]) < 1e-8 and radius == pytest.approx(0.3, abs=1e-8)
    assert abs(normal[2]) == pytest.approx(1.0) and rms < 1e-9


def test_a_very_wide_arc_counts_as_a_line():
    positions, _ = door_path([0, 0, 1], [0, 0, 0.5], [5.0, 0, 0], arc_deg=3, n=20, noise_m=2e-4)
    axis = fit_trajectory(positions)
    assert axis.joint_type is JointType.PRISMATIC
    forced = fit_trajectory(positions, joint=JointType.REVOLUTE)
    assert isinstance(forced, NoAxis) and "too straight" in forced.reason


def test_gripper_rotation_marks_a_short_arc_revolute():
    """A 6 deg arc is too flat for the positions alone, but the gripper turned with the door."""
    positions, quaternions = door_path([0, 0, 1], [0.6, 0.2, 0.5], [0, -0.4, 0], arc_deg=6, noise_m=1e-3)
    assert fit_trajectory(positions).joint_type is JointType.PRISMATIC
    axis = fit_trajectory(positions, quaternions)
    assert axis.joint_type is JointType.REVOLUTE and angle_deg(axis.direction, [0, 0, 1]) < 0.5


def test_degenerate_inputs_give_no_axis_with_a_reason():
    positions, quaternions = drawer_path([1, 0, 0])
    cases = {
        "two samples": fit_trajectory(positions[:2]),
        "no motion": fit_trajectory(np.tile(positions[:1], (10, 1))),
        "2 mm of motion": fit_trajectory(positions[0] + np.outer(np.linspace(0, 0.002, 10), [1, 0, 0])),
        "collinear as a door": fit_trajectory(positions, joint=JointType.REVOLUTE),
        "NaN": fit_trajectory(np.where(np.arange(60).reshape(20, 3) == 7, np.nan, positions)),
        "bad shape": fit_trajectory(positions[:, :2]),
        "zero quaternion": fit_trajectory(positions, np.zeros((20, 4))),
        "quaternion count": fit_trajectory(positions, quaternions[:5]),
        "empty": fit_trajectory(np.zeros((0, 3))),
    }
    for name, result in cases.items():
        assert isinstance(result, NoAxis), name
        assert len(result.reason) > 10, name
    assert "motion" in cases["no motion"].reason and "motion" in cases["2 mm of motion"].reason
    with pytest.raises(ValueError, match="collinear"):
        fit_circle_3d(positions)
    with pytest.raises(ValueError, match="coincide"):
        fit_line(np.ones((5, 3)))
    with pytest.raises(ValueError, match="at least 3"):
        fit_circle_3d(positions[:2])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(*[st.floats(-1, 1, allow_nan=False, width=32)] * 3), min_size=0, max_size=12
    ),
    st.sampled_from([None, JointType.PRISMATIC, JointType.REVOLUTE]),
)
def test_arbitrary_input_never_crashes_or_gives_nan(points, joint):
    result = fit_trajectory(np.array(points, float).reshape(-1, 3), joint=joint)
    if isinstance(result, Axis):
        values = np.concatenate([result.origin, result.direction, [result.confidence, result.residual_m]])
        assert np.all(np.isfinite(values)) and 0.0 <= result.confidence <= 1.0
        assert np.linalg.norm(result.direction) == pytest.approx(1.0)
    else:
        assert result.reason


def test_one_glitch_in_a_standing_path_is_no_motion():
    """Hypothesis found it: the 1 m spread is one glitch, dropped, which left a single place to fit a line to."""
    points = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 1], [0, 0, 0], [0, 0, 0]])
    for joint in (None, JointType.PRISMATIC, JointType.REVOLUTE):
        result = fit_trajectory(points, joint=joint)
        assert isinstance(result, NoAxis) and "not enough motion" in result.reason


def test_parse_trajectory_text_formats():
    text = "# x y z\n0 0 0\n\n0.01, 0.0, 0.0  # comment\n0.02\t0 0\n"
    positions, quaternions = parse_trajectory_text(text)
    assert quaternions is None and positions.shape == (3, 3) and positions[1, 0] == 0.01
    positions, quaternions = parse_trajectory_text("0 0 0 0 0 0 2\n1,2,3,0,0,1,0\n")
    assert positions.tolist() == [[0, 0, 0], [1, 2, 3]]
    assert quaternions.tolist() == [[0, 0, 0, 1], [0, 0, 1, 0]]
    positions, quaternions = parse_trajectory_text("# nothing\n")
    assert positions.shape == (0, 3) and quaternions is None


@pytest.mark.parametrize(
    "text, message",
    [
        ("0 0 0\n1 2\n", "line 2: expected 3 values"),
        ("0 0 0\n0 0 0 0 0 0 1\n", "line 2: 7 values but earlier lines have 3"),
        ("0 0 0\n\n0 x 0\n", "line 3: not a number"),
        ("0 0 nan\n", "line 1: NaN or inf"),
        ("0 0 0 0 0 0 0\n", "line 1: zero quaternion"),
    ],
)
def test_parse_trajectory_text_errors_name_the_line(text, message):
    with pytest.raises(ValueError, match=message):
        parse_trajectory_text(text)


def observations(poses) -> list[Observation]:
    box = Box(np.zeros(3), np.eye(3), np.ones(3))
    return [Observation(i, 0.1 * i, np.zeros((0, 3)), box, pose) for i, pose in enumerate(poses)]


def test_trajectory_estimator_uses_the_gripper_poses():
    axis_direction, hinge, arm = DOORS["tilted"]
    positions, quaternions = door_path(axis_direction, hinge, arm, arc_deg=25, n=10)
    poses = np.tile(np.eye(4), (10, 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(quaternions).as_matrix()
    poses[:, :3, 3] = positions
    estimator = TrajectoryEstimator()
    assert estimator.name == "trajectory"
    axis = estimator.estimate(observations(poses))
    assert axis.joint_type is JointType.REVOLUTE and angle_deg(axis.direction, axis_direction) < 1e-3
    assert isinstance(estimator.estimate(observations(poses), JointType.PRISMATIC), Axis)

    missing = estimator.estimate(observations([*poses[:5], None, *poses[6:]]))
    assert isinstance(missing, NoAxis) and "missing in 1 of 10" in missing.reason
    assert isinstance(estimator.estimate(observations(poses[:2])), NoAxis)
    assert isinstance(estimator.estimate([]), NoAxis)
