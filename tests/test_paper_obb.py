"""The paper's box estimator on synthetic drawers and doors (surface samples, the real pipeline)."""

from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from deploy.geometry.boxes import yaw_box
from deploy.geometry.estimators.base import Observation
from deploy.geometry.estimators.paper_obb import PaperOBBEstimator
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.moving_part import moving_part
from deploy.geometry.types import Axis, JointType, NoAxis

CENTER = np.array([0.9, 0.15, 0.5])  # cabinet 0.4 deep (local x, pointing away), 0.5 wide, 0.6 tall
EXTENT = np.array([0.4, 0.5, 0.6])
Z = np.array([0.0, 0.0, 1.0])


def face(center, u, v, size_u, size_v, step=0.005) -> np.ndarray:
    a = np.linspace(-size_u / 2, size_u / 2, int(np.ceil(size_u / step)) + 1)
    b = np.linspace(-size_v / 2, size_v / 2, int(np.ceil(size_v / step)) + 1)
    A, B = np.meshgrid(a, b)
    return np.asarray(center) + A.reshape(-1, 1) * u + B.reshape(-1, 1) * v


def box_faces(center, extent, faces) -> np.ndarray:
    """Samples of an axis-aligned box's faces (local frame); face 2*i + (0 or 1) is the -/+ side of axis i."""
    out = []
    for f in faces:
        i, sign = f // 2, (-1, 1)[f % 2]
        j, k = [a for a in range(3) if a != i]
        c = np.array(center, float)
        c[i] += sign * extent[i] / 2
        out.append(face(c, np.eye(3)[j], np.eye(3)[k], extent[j], extent[k]))
    return np.concatenate(out)


def to_world(local: np.ndarray, yaw: float) -> np.ndarray:
    return CENTER + local @ Rotation.from_euler("z", yaw).as_matrix().T


def drawer_cloud(yaw: float, opening_m: float) -> np.ndarray:
    """Cabinet front (minus the drawer's opening), top and left side; the drawer's front, top and side."""
    front = box_faces([0, 0, 0], EXTENT, [0])
    in_opening = (np.abs(front[:, 1]) <= 0.2) & (front[:, 2] >= 0.05) & (front[:, 2] <= 0.2)
    drawer = box_faces([-0.2 + 0.175 - opening_m, 0.0, 0.125], [0.35, 0.4, 0.15], [0, 5, 2])
    return to_world(np.concatenate([front[~in_opening], box_faces([0, 0, 0], EXTENT, [5, 2]), drawer]), yaw)


def door_cloud(yaw: float, hinge_side: int, angle_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cabinet top and left side, and a 2 cm door in front of it: its front, top and free edge.

    Returns the cloud, the hinge point and the true axis direction (opening = positive rotation about it).
    """
    panel = box_faces([-0.21, 0.0, 0.0], [0.02, 0.5, 0.6], [0, 5, 2 if hinge_side > 0 else 3])
    hinge = np.array([-0.21, hinge_side * 0.25, 0.0])
    direction = -hinge_side * Z  # the free edge swings towards the front (local -x)
    panel = hinge + (panel - hinge) @ Rotation.from_rotvec(angle_rad * direction).as_matrix().T
    cloud = np.concatenate([box_faces([0, 0, 0], EXTENT, [5, 2]), panel])
    return to_world(cloud, yaw), to_world(hinge[None], yaw)[0], direction


def observations(clouds: list[np.ndarray]) -> list[Observation]:
    body_box = yaw_box(clouds[0])
    return [Observation(i, 0.1 * i, moving_part(c, body_box), body_box) for i, c in enumerate(clouds)]


@cache
def drawer_window(yaw: float, n_frames: int = 11) -> tuple[Observation, ...]:
    return tuple(observations([drawer_cloud(yaw, 0.02 * i) for i in range(n_frames)]))


@cache
def door_window(yaw: float, hinge_side: int, n_frames: int = 11):
    clouds = [door_cloud(yaw, hinge_side, np.radians(3.0 * i)) for i in range(n_frames)]
    return tuple(observations([c for c, _, _ in clouds])), clouds[0][1], clouds[0][2]


@pytest.mark.parametrize("yaw", [0.2, -0.35])
@pytest.mark.parametrize("joint", [JointType.PRISMATIC, None])
def test_drawer_direction_is_recovered(yaw, joint):
    result = PaperOBBEstimator().estimate(drawer_window(yaw), joint)
    assert isinstance(result, Axis) and result.joint_type is JointType.PRISMATIC
    front_normal = -Rotation.from_euler("z", yaw).as_matrix()[:, 0]
    assert axis_angle_error_deg(result.direction, front_normal) < 0.05  # 120 yaw angles: not exact
    assert result.direction @ front_normal > 0  # it opens outwards
    assert 0.0 < result.confidence <= 1.0 and result.residual_m >= 0.0


@pytest.mark.parametrize("yaw", [0.2, -0.35])
@pytest.mark.parametrize("hinge_side", [1, -1])
@pytest.mark.parametrize("joint", [JointType.REVOLUTE, None])
def test_door_axis_is_recovered(yaw, hinge_side, joint):
    window, hinge, direction = door_window(yaw, hinge_side)
    result = PaperOBBEstimator().estimate(window, joint)
    assert isinstance(result, Axis) and result.joint_type is JointType.REVOLUTE
    assert result.direction == pytest.approx(direction)  # opening is a positive rotation about it
    door_center = to_world(np.array([[-0.21, 0.0, 0.0]]), yaw)[0]
    assert axis_position_error_m(hinge, direction, result.origin, result.direction, at=door_center) < 0.01
    assert 0.0 < result.confidence <= 1.0


def test_exact_boxes_give_the_axis_exactly():
    window, hinge, direction = door_window(0.2, 1)
    result = PaperOBBEstimator(n_angles=None).estimate(window, JointType.REVOLUTE)
    assert axis_angle_error_deg(result.direction, direction) == 0.0
    assert axis_position_error_m(hinge, direction, result.origin, result.direction) < 1e-6
    result = PaperOBBEstimator(n_angles=None).estimate(drawer_window(0.2), JointType.PRISMATIC)
    front_normal = -Rotation.from_euler("z", 0.2).as_matrix()[:, 0]
    assert result.direction == pytest.approx(front_normal, abs=1e-9)


def test_parallel_midlines_give_no_axis():
    result = PaperOBBEstimator().estimate(drawer_window(0.2), JointType.REVOLUTE)
    assert isinstance(result, NoAxis) and result.reason.startswith("midlines parallel")


@pytest.mark.parametrize("joint", [JointType.PRISMATIC, JointType.REVOLUTE, None])
def test_no_motion_gives_no_axis(joint):
    still = [drawer_window(0.2)[5]] * 6
    result = PaperOBBEstimator().estimate(still, joint)
    assert isinstance(result, NoAxis) and result.reason.startswith("not enough motion yet")
    assert "travelled 0 mm of 10 mm" in result.reason


@pytest.mark.parametrize("joint", [JointType.PRISMATIC, JointType.REVOLUTE, None])
def test_empty_moving_part_or_window_gives_no_axis(joint):
    window = drawer_window(0.2)
    assert len(window[0].moving) == 0  # closed: nothing outside the body box
    result = PaperOBBEstimator().estimate(window[:1], joint)
    assert isinstance(result, NoAxis) and "0 of 200 points" in result.reason
    assert isinstance(PaperOBBEstimator().estimate([], joint), NoAxis)


def test_small_travel_gives_no_axis_until_it_is_enough():
    window = drawer_window(0.2)  # the moving part's box centre moves 1 cm per frame (half the opening)
    assert isinstance(PaperOBBEstimator(min_travel_m=0.05).estimate(window[-5:]), NoAxis)
    assert isinstance(PaperOBBEstimator(min_travel_m=0.05).estimate(window[-6:]), Axis)


def same(a: Axis, b: Axis) -> bool:
    same_line = np.allclose(a.origin, b.origin) and np.allclose(a.direction, b.direction)
    return a.joint_type == b.joint_type and same_line


def test_prismatic_window_has_at_most_10_frames_and_enough_points():
    window = list(drawer_window(0.2, n_frames=14))
    estimator = PaperOBBEstimator()
    full = estimator.estimate(window, JointType.PRISMATIC)
    assert same(full, estimator.estimate(window[-10:], JointType.PRISMATIC))
    assert not same(full, estimator.estimate(window[-9:], JointType.PRISMATIC))
    assert full.origin == pytest.approx(yaw_box(window[-10].moving).center)
    # a frame with < 1000 moving points stops the window
    window[8] = Observation(8, 0.8, window[8].moving[:900], window[8].body_box)
    shortened = estimator.estimate(window[9:], JointType.PRISMATIC)
    assert same(estimator.estimate(window, JointType.PRISMATIC), shortened)


def test_revolute_window_has_at_most_8_frames_and_elongated_boxes():
    window = list(door_window(0.2, 1)[0])
    estimator = PaperOBBEstimator()
    full = estimator.estimate(window, JointType.REVOLUTE)
    assert same(full, estimator.estimate(window[-8:], JointType.REVOLUTE))
    assert not same(full, estimator.estimate(window[-7:], JointType.REVOLUTE))
    # a squarish moving part (side ratio < 1.2) stops the window
    patch = np.stack(np.meshgrid(*[np.arange(10) * 0.005] * 2, [0.0, 0.01]), axis=-1).reshape(-1, 3)
    square = window[5].moving.mean(axis=0) + patch
    assert yaw_box(square).extent[0] < 1.2 * yaw_box(square).extent[1] and len(square) >= 200
    window[5] = Observation(5, 0.5, square, window[5].body_box)
    shortened = estimator.estimate(window[6:], JointType.REVOLUTE)
    assert same(estimator.estimate(window, JointType.REVOLUTE), shortened)


points_strategy = st.one_of(
    st.lists(st.tuples(*[st.integers(-3, 3)] * 3), max_size=40).map(
        lambda p: np.array(p, float).reshape(-1, 3) * 0.01
    ),
    st.integers(0, 30).map(lambda n: np.c_[np.linspace(0, 0.3, n), np.linspace(0, 0.1, n), np.zeros(n)]),
    st.just(np.array([[0.1, 0.2, np.nan], [0.1, 0.2, 0.3], [0.1, 0.2, 0.3], [0.4, 0.2, 0.3]])),
)


@settings(max_examples=150, deadline=None)
@given(clouds=st.lists(points_strategy, min_size=1, max_size=4), joint=st.sampled_from([None, *JointType]))
def test_never_nan_on_degenerate_input(clouds, joint):
    body_box = yaw_box(np.zeros((1, 3)))
    window = [Observation(i, float(i), c, body_box) for i, c in enumerate(clouds)]
    result = PaperOBBEstimator(min_points=1, min_travel_m=1e-6).estimate(window, joint)
    if isinstance(result, Axis):
        values = np.r_[result.origin, result.direction, result.confidence, result.residual_m]
        assert np.all(np.isfinite(values))
        assert np.linalg.norm(result.direction) == pytest.approx(1.0)
        assert 0.0 <= result.confidence <= 1.0
    else:
        assert isinstance(result, NoAxis) and result.reason
