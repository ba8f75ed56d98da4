"""Back-projection of depth images and rigid transforms."""

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

from deploy.geometry.cloud import depth_to_points, transform_points

K = np.array([[600.0, 0.0, 319.5], [0.0, 610.0, 239.5], [0.0, 0.0, 1.0]])


def pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def test_known_pixels():
    depth = np.zeros((480, 640))
    depth[240, 320] = 1.0  # row v = 240, column u = 320: half a pixel right of and below the centre
    assert depth_to_points(depth, K) == pytest.approx(np.array([[0.5 / 600, 0.5 / 610, 1.0]]))
    depth = np.zeros((480, 640))
    depth[100, 50] = 2.0
    (x, y, z), = depth_to_points(depth, K)
    assert (x, y, z) == pytest.approx(((50 - 319.5) * 2 / 600, (100 - 239.5) * 2 / 610, 2.0))


def test_reprojection_round_trip():
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.4, 3.0, (48, 64))
    points = depth_to_points(depth, K)
    pixels = points @ K.T
    pixels = pixels[:, :2] / pixels[:, 2:]
    v, u = np.mgrid[0:48, 0:64]
    assert pixels == pytest.approx(np.stack([u.ravel(), v.ravel()], axis=1), abs=1e-9)
    assert points[:, 2] == pytest.approx(depth.ravel())


def test_matches_open3d_back_projection():
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.5, 2.0, (60, 80)).astype(np.float32)
    intrinsic = o3d.camera.PinholeCameraIntrinsic(80, 60, 600.0, 610.0, 39.5, 29.5)
    ref = o3d.geometry.PointCloud.create_from_depth_image(
        o3d.geometry.Image(depth), intrinsic, depth_scale=1.0, depth_trunc=10.0
    )
    K_small = np.array([[600.0, 0.0, 39.5], [0.0, 610.0, 29.5], [0.0, 0.0, 1.0]])
    assert depth_to_points(depth, K_small) == pytest.approx(np.asarray(ref.points), abs=1e-6)


def test_invalid_depth_and_mask_are_dropped():
    depth = np.full((4, 5), 1.0)
    depth[0, 0], depth[0, 1], depth[0, 2], depth[0, 3] = 0.0, np.nan, np.inf, -1.0
    depth[1, 0], depth[1, 1] = 0.3, 5.0  # outside [0.4, 4.0]
    mask = np.ones((4, 5), dtype=bool)
    mask[3, :] = False
    points = depth_to_points(depth, K, mask=mask, min_depth_m=0.4, max_depth_m=4.0)
    assert len(points) == 20 - 5 - 4 - 2  # row 3 masked, 4 invalid depths, 2 out of range
    assert np.all(np.isfinite(points))
    assert points[:, 2] == pytest.approx(np.ones(len(points)))
    assert depth_to_points(np.zeros((4, 5)), K).shape == (0, 3)


def test_pose_moves_points_to_the_base_frame():
    rng = np.random.default_rng(2)
    depth = rng.uniform(0.5, 2.0, (30, 40))
    T = pose([0.3, -1.2, 0.5], [0.4, -0.1, 1.3])
    camera = depth_to_points(depth, K)
    base = depth_to_points(depth, K, T_base_camera=T)
    assert base == pytest.approx(transform_points(T, camera))
    # distances to the camera centre are kept, and the camera centre maps to T's translation
    assert np.linalg.norm(base - T[:3, 3], axis=1) == pytest.approx(np.linalg.norm(camera, axis=1))


def test_transform_points():
    T = pose([0.0, 0.0, np.pi / 2], [1.0, 2.0, 3.0])
    assert transform_points(T, np.array([[1.0, 0.0, 0.0]])) == pytest.approx(np.array([[1.0, 3.0, 3.0]]))
    assert transform_points(T, np.zeros((0, 3))).shape == (0, 3)
    T2 = pose([0.1, 0.2, 0.3], [0.0, 1.0, 0.0])
    points = np.random.default_rng(3).normal(size=(10, 3))
    chained = transform_points(T2, transform_points(T, points))
    assert transform_points(T2 @ T, points) == pytest.approx(chained)


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="depth"):
        depth_to_points(np.zeros(5), K)
    with pytest.raises(ValueError, match="K must be"):
        depth_to_points(np.zeros((2, 2)), np.eye(2))
    with pytest.raises(ValueError, match="mask shape"):
        depth_to_points(np.zeros((2, 2)), K, mask=np.ones((3, 3), dtype=bool))
    with pytest.raises(ValueError, match="4x4"):
        transform_points(np.eye(3), np.zeros((1, 3)))
