"""Yaw-only and 3D oriented boxes, the front direction, handle removal."""

from functools import partial

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deploy.geometry.boxes import extend_behind, front_direction, oriented_box, remove_handle, yaw_box
from deploy.geometry.types import Box


def rot_z(yaw: float) -> np.ndarray:
    return Rotation.from_euler("z", yaw).as_matrix()


def face(center, u, v, size_u, size_v, step=0.005) -> np.ndarray:
    """Grid samples (edges included) of a rectangle centred at `center` spanned by unit u, v."""
    a = np.linspace(-size_u / 2, size_u / 2, int(np.ceil(size_u / step)) + 1)
    b = np.linspace(-size_v / 2, size_v / 2, int(np.ceil(size_v / step)) + 1)
    A, B = np.meshgrid(a, b)
    return np.asarray(center) + A.reshape(-1, 1) * u + B.reshape(-1, 1) * v


def box_surface(center, R, extent, step=0.01, faces=range(6)) -> np.ndarray:
    """Samples of a box's faces; face 2*i + (0 or 1) is the -/+ side along axis i."""
    out = []
    for f in faces:
        i, sign = f // 2, (-1, 1)[f % 2]
        j, k = [a for a in range(3) if a != i]
        c = np.asarray(center) + sign * extent[i] / 2 * R[:, i]
        out.append(face(c, R[:, j], R[:, k], extent[j], extent[k], step))
    return np.concatenate(out)


def yaw_of(box: Box) -> float:
    return float(np.arctan2(box.rotation[1, 0], box.rotation[0, 0]))


def angle_mod(a: float, period: float) -> float:
    """Distance of angle a to 0 modulo period."""
    r = np.mod(a, period)
    return float(min(r, period - r))


def brute_force_yaw_box(points: np.ndarray, n_angles: int) -> tuple[float, np.ndarray]:
    """Smallest-area yaw over all points (no hull) and the sorted horizontal extents."""
    best = None
    for yaw in np.pi / 2 * np.arange(n_angles) / n_angles:
        local = points[:, :2] @ rot_z(yaw)[:2, :2]
        ext = np.ptp(local, axis=0)
        if best is None or ext.prod() < best[0]:
            best = (ext.prod(), yaw, np.sort(ext)[::-1])
    return best[1], best[2]


@pytest.mark.parametrize("yaw", [0.0, 0.4, -1.1, 2.5])
def test_yaw_box_exact_mode_recovers_a_rotated_box(yaw):
    center, extent = np.array([0.7, -0.2, 0.4]), np.array([0.6, 0.3, 0.5])
    points = box_surface(center, rot_z(yaw), extent)
    box = yaw_box(points, n_angles=None)
    assert angle_mod(yaw_of(box) - yaw, np.pi) < 1e-9
    assert box.extent == pytest.approx(extent, abs=1e-9)
    assert box.center == pytest.approx(center, abs=1e-9)
    assert box.rotation == pytest.approx(rot_z(yaw_of(box)))


@pytest.mark.parametrize("yaw", [0.4, -1.1, np.radians(15.0)])
def test_yaw_box_120_angles_is_within_the_grid_resolution(yaw):
    center, extent = np.array([0.7, -0.2, 0.4]), np.array([0.6, 0.3, 0.5])
    points = box_surface(center, rot_z(yaw), extent)
    box = yaw_box(points)
    assert np.degrees(angle_mod(yaw_of(box) - yaw, np.pi)) <= 0.375 + 1e-9
    slack = 0.6 * np.sin(np.radians(0.375))  # the long side tilted by half a grid step
    assert box.extent == pytest.approx(extent, abs=slack)
    assert box.center == pytest.approx(center, abs=slack)
    assert np.all(box.contains(points, 1e-9))
    if yaw == np.radians(15.0):  # on the 0.75 deg grid: exact
        assert box.extent == pytest.approx(extent, abs=1e-9)


def test_yaw_box_puts_the_longer_side_first():
    points = box_surface(np.zeros(3), rot_z(0.3), np.array([0.2, 0.7, 0.1]))
    box = yaw_box(points)
    assert box.extent[0] > box.extent[1]
    assert abs(box.rotation[:, 0] @ rot_z(0.3)[:, 1]) > np.cos(np.radians(0.4))
    assert np.linalg.det(box.rotation) == pytest.approx(1.0)


def test_yaw_box_hull_gives_the_same_box_as_all_points():
    rng = np.random.default_rng(0)
    for _ in range(5):
        points = rng.normal(size=(500, 3)) * rng.uniform(0.05, 1.0, 3) + rng.uniform(-1, 1, 3)
        box = yaw_box(points)
        yaw, ext = brute_force_yaw_box(points, 120)
        assert box.extent[:2] == pytest.approx(ext, abs=1e-12)
        assert angle_mod(yaw_of(box) - yaw, np.pi / 2) < 1e-12


@pytest.mark.parametrize(
    "points",
    [
        np.array([[0.1, 0.2, 0.3]]),
        np.array([[0.1, 0.2, 0.3], [0.1, 0.2, 0.3]]),
        np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.5]]),
        np.c_[np.linspace(0, 1, 50), np.linspace(0, 1, 50) * 0.5, np.zeros(50)],
        np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [np.nan, 0.0, 0.0]]),
    ],
)
@pytest.mark.parametrize("n_angles", [120, None])
def test_yaw_box_degenerate_input_gives_a_finite_box(points, n_angles):
    box = yaw_box(points, n_angles)
    assert np.all(np.isfinite(box.center)) and np.all(np.isfinite(box.extent))
    finite = points[np.all(np.isfinite(points), axis=1)]
    assert np.all(box.contains(finite, 1e-9))


def test_box_of_no_points_raises():
    with pytest.raises(ValueError, match="no finite points"):
        yaw_box(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="no finite points"):
        oriented_box(np.full((3, 3), np.nan))


def test_oriented_box_fits_a_tilted_box():
    R = Rotation.from_rotvec([0.3, -0.2, 0.7]).as_matrix()
    center, extent = np.array([0.5, 0.1, 0.8]), np.array([0.5, 0.3, 0.2])
    points = box_surface(center, R, extent, step=0.02)
    box = oriented_box(points)
    assert np.sort(box.extent) == pytest.approx(np.sort(extent), abs=2e-3)
    assert box.center == pytest.approx(center, abs=2e-3)
    assert np.linalg.det(box.rotation) == pytest.approx(1.0)
    assert box.rotation.T @ box.rotation == pytest.approx(np.eye(3), abs=1e-9)
    assert np.all(box.contains(points, 1e-6))


@pytest.mark.parametrize(
    "points",
    [
        np.c_[np.random.default_rng(1).uniform(0, 1, (200, 2)), np.zeros(200)],  # flat
        np.c_[np.linspace(0, 1, 20), np.linspace(0, 2, 20), np.linspace(0, 3, 20)],  # collinear
        np.array([[0.1, 0.2, 0.3]] * 3),
    ],
)
def test_oriented_box_degenerate_input(points):
    box = oriented_box(points)
    assert np.all(np.isfinite(box.extent)) and np.linalg.det(box.rotation) == pytest.approx(1.0)
    assert np.all(box.contains(points, 1e-9))


def cabinet(yaw: float):
    """A cabinet 0.4 deep, 0.5 wide, 0.6 tall facing -x_local, with its front, top and left faces."""
    R = rot_z(yaw)
    center, extent = np.array([0.9, 0.2, 0.5]), np.array([0.4, 0.5, 0.6])
    normal = -R[:, 0]
    points = box_surface(center, R, extent, step=0.005, faces=[0, 5, 2])
    return points, center, R, extent, normal


@pytest.mark.parametrize("yaw", [0.0, 0.3, -0.4])
def test_front_direction_faces_the_viewpoint(yaw):
    _, center, R, extent, normal = cabinet(yaw)
    box = Box(center, R, extent)
    assert front_direction(box, center + 1.0 * normal + [0, 0, 0.6]) == pytest.approx(normal)
    # far to the side of this wide shallow box the ray still leaves through the front face
    wide = Box(center, R, np.array([0.3, 0.8, 0.6]))
    assert front_direction(wide, center + 1.0 * normal + 1.2 * R[:, 1]) == pytest.approx(normal)
    assert front_direction(box, center + 2.0 * R[:, 1]) == pytest.approx(R[:, 1])


def bar_handle(center, R, normal):
    """A vertical bar 12 cm long, 1 cm thick, its front 4 cm in front of the face, on two 1 cm posts."""
    front = center + 0.2 * normal + 0.15 * R[:, 1]
    bar = box_surface(front + 0.035 * normal, R, np.array([0.01, 0.015, 0.12]), step=0.003)
    posts = [box_surface(front + 0.015 * normal + dz * R[:, 2], R, np.array([0.03, 0.01, 0.01]), step=0.003)
             for dz in (-0.05, 0.05)]
    return np.concatenate([bar, *posts])


@pytest.mark.parametrize(
    "box_fn", [yaw_box, partial(yaw_box, n_angles=None), oriented_box], ids=["yaw120", "yaw-exact", "3d"]
)
def test_remove_handle_removes_a_protruding_bar(box_fn):
    body, center, R, extent, normal = cabinet(np.radians(15.0))
    handle = bar_handle(center, R, normal)
    points = np.concatenate([body, handle])
    viewpoint = center + 1.0 * normal + [0, 0, 0.5]
    body_box, body_points, handle_points = remove_handle(points, viewpoint, box_fn=box_fn)
    ahead = (handle - center) @ normal - 0.2  # how far in front of the face each handle point is
    found = {tuple(p) for p in handle_points}
    assert all(tuple(p) in found for p in handle[ahead > 0.008 + 1e-9])
    assert not any(tuple(p) in found for p in handle[ahead <= 0.008])
    assert not any(tuple(p) in found for p in body)
    assert len(body_points) + len(handle_points) == len(points)
    # the body box is tight: at most the margin (what is left of the posts) deeper than the cabinet
    assert np.sort(body_box.extent) == pytest.approx(np.sort(extent), abs=0.0085)
    assert abs(body_box.extent @ np.abs(body_box.rotation.T @ normal) - 0.4) <= 0.0085


def test_remove_handle_without_handle_changes_nothing():
    body, center, R, extent, normal = cabinet(0.2)
    body_box, body_points, handle_points = remove_handle(body, center + normal)
    assert handle_points.shape == (0, 3)
    assert len(body_points) == len(body)
    reference = yaw_box(body)
    assert body_box.extent == pytest.approx(reference.extent)
    assert body_box.center == pytest.approx(reference.center)


def test_remove_handle_with_depth_noise():
    rng = np.random.default_rng(4)
    body, center, R, extent, normal = cabinet(0.1)
    handle = bar_handle(center, R, normal)
    body = body + rng.normal(0, 0.0015, body.shape)
    handle = handle + rng.normal(0, 0.0015, handle.shape)
    body_box, _, handle_points = remove_handle(np.concatenate([body, handle]), center + normal)
    found = {tuple(p) for p in handle_points}
    ahead = (handle - center) @ normal - 0.2
    assert all(tuple(p) in found for p in handle[ahead > 0.02])
    assert not any(tuple(p) in found for p in body)
    assert abs(body_box.extent @ np.abs(body_box.rotation.T @ normal) - 0.4) <= 0.015


def test_extend_behind_keeps_the_front_and_the_sides_and_reaches_back():
    rotation = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    box = Box(np.array([1.0, 0.5, 0.4]), rotation, np.array([0.4, 0.6, 0.8]))
    front, side, up = rotation.T  # the +x face looks at the camera
    deep = extend_behind(box, front + 0.2 * side, 1.0)  # a rough front normal picks the nearest face
    np.testing.assert_allclose((deep.corners() @ front).max(), (box.corners() @ front).max())
    np.testing.assert_allclose((deep.corners() @ front).min(), (box.corners() @ front).min() - 1.0)
    np.testing.assert_allclose(deep.extent[1:], box.extent[1:])
    behind, in_front = box.center - 1.1 * front, box.center + 0.25 * front
    assert deep.contains(behind[None])[0] and not box.contains(behind[None])[0]
    assert not deep.contains(np.array([in_front, box.center + 0.35 * side, box.center + 0.45 * up])).any()
