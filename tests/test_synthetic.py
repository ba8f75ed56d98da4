"""Synthetic cabinets, the box ray caster and synthetic sequences."""

import json
import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deploy.geometry.types import Box, JointType
from deploy.synthetic import SyntheticCabinet, render, render_rgbd, synthetic_sequence, write_sequence
from deploy.synthetic.sequence import D415_640X480, look_at, random_camera_pose
from drivers.camera.base import Intrinsics, SegLabel
from drivers.camera.depth_noise import DepthNoise
from drivers.camera.frames_dir import FramesRecording

SMALL = Intrinsics(160, 120, 150.0, 150.0, 79.5, 59.5)
CAMERA_AT_ORIGIN_LOOKING_X = look_at(np.zeros(3), np.array([1.0, 0.0, 0.0]))


def pixel_points(depth: np.ndarray, intr: Intrinsics, T: np.ndarray) -> np.ndarray:
    """Back-project the valid pixels to base-frame points (N, 3)."""
    v, u = np.nonzero(depth > 0)
    z = depth[v, u].astype(float)
    cam = np.stack([(u - intr.cx) / intr.fx * z, (v - intr.cy) / intr.fy * z, z], axis=1)
    return cam @ T[:3, :3].T + T[:3, 3]


def inside_any(points: np.ndarray, boxes: list[Box], margin_m: float) -> np.ndarray:
    return np.any([box.contains(points, margin_m) for box in boxes], axis=0)


def rigid_motion(a: Box, b: Box) -> np.ndarray:
    """4x4 transform taking box a's pose to box b's pose."""
    Ta, Tb = np.eye(4), np.eye(4)
    Ta[:3, :3], Ta[:3, 3] = a.rotation, a.center
    Tb[:3, :3], Tb[:3, 3] = b.rotation, b.center
    return Tb @ np.linalg.inv(Ta)


# ---- ray caster ----


def test_box_facing_the_camera_has_the_analytic_depth_and_outline():
    box = Box(np.array([2.0, 0.1, -0.05]), np.eye(3), np.array([0.2, 1.0, 0.6]))
    depth, labels = render([(box, SegLabel.HANDLE)], SMALL, CAMERA_AT_ORIGIN_LOOKING_X)
    assert depth.dtype == np.float32 and labels.dtype == np.uint8 and depth.shape == (120, 160)
    hit = depth > 0
    np.testing.assert_allclose(depth[hit], 1.9, atol=1e-6)
    assert np.all(labels[hit] == SegLabel.HANDLE) and np.all(labels[~hit] == 0)
    # camera x = -y_base, camera y = -z_base: the front face spans these pixel ranges
    u = np.arange(160)
    v = np.arange(120)
    y_cam = (u - SMALL.cx) / SMALL.fx * 1.9
    z_cam = (v - SMALL.cy) / SMALL.fy * 1.9
    expected = (np.abs(z_cam - 0.05) <= 0.3)[:, None] & (np.abs(-y_cam - 0.1) <= 0.5)[None, :]
    np.testing.assert_array_equal(hit, expected)


def test_rotated_box_depth_at_the_optical_axis():
    a = 0.4
    turn = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    box = Box(np.array([2.0, 0.0, 0.0]), turn, np.array([a, a, 1.0]))
    intr = Intrinsics(41, 41, 50.0, 50.0, 20.0, 20.0)
    depth, _ = render([(box, SegLabel.OBJECT)], intr, CAMERA_AT_ORIGIN_LOOKING_X)
    assert depth[20, 20] == pytest.approx(2.0 - a / np.sqrt(2), abs=1e-6)
    assert depth[20, 21] > depth[20, 20] and depth[20, 19] > depth[20, 20]


def test_nearest_box_wins_and_misses_are_empty():
    far = Box(np.array([3.0, 0.0, 0.0]), np.eye(3), np.array([0.1, 2.0, 2.0]))
    near = Box(np.array([1.5, 0.0, 0.0]), np.eye(3), np.array([0.1, 0.2, 0.2]))
    behind = Box(np.array([-1.0, 0.0, 0.0]), np.eye(3), np.array([0.5, 5.0, 5.0]))
    for order in ([far, near, behind], [behind, near, far]):
        labelled = [(b, SegLabel.OBJECT if b is far else SegLabel.HANDLE) for b in order]
        depth, labels = render(labelled, SMALL, CAMERA_AT_ORIGIN_LOOKING_X)
        assert depth[60, 80] == pytest.approx(1.45) and labels[60, 80] == SegLabel.HANDLE
        assert depth[30, 40] == pytest.approx(2.95) and labels[30, 40] == SegLabel.OBJECT
    depth, labels = render([(behind, SegLabel.OBJECT)], SMALL, CAMERA_AT_ORIGIN_LOOKING_X)
    assert not depth.any() and not labels.any()
    around = Box(np.zeros(3), np.eye(3), np.ones(3))  # the camera inside a box sees nothing of it
    assert not render([(around, SegLabel.OBJECT)], SMALL, CAMERA_AT_ORIGIN_LOOKING_X)[0].any()


def test_colour_is_shaded_by_the_surface_angle():
    face_on = Box(np.array([2.0, 0.5, 0.0]), np.eye(3), np.array([0.2, 0.6, 0.6]))
    turn = Rotation.from_euler("z", 60, degrees=True).as_matrix()
    turned = Box(np.array([2.0, -0.5, 0.0]), turn, np.array([0.02, 0.6, 0.6]))
    scene = [(face_on, SegLabel.OBJECT), (turned, SegLabel.OBJECT)]
    color, depth, labels = render_rgbd(scene, SMALL, CAMERA_AT_ORIGIN_LOOKING_X)
    assert color.dtype == np.uint8 and color.shape == (120, 160, 3)
    left, right = color[60, 40].astype(int), color[60, 120].astype(int)  # camera x = -y_base
    assert labels[60, 40] == labels[60, 120] == SegLabel.OBJECT
    assert left.sum() > right.sum() > 0


def test_render_speed_640x480_with_15_boxes():
    cabinet = SyntheticCabinet(kind="drawer")
    boxes = [(Box(np.array([0.0, 0.0, -0.01]), np.eye(3), np.array([6.0, 6.0, 0.02])), SegLabel.BACKGROUND)]
    boxes += cabinet.parts(0.2)
    assert len(boxes) >= 14
    T = random_camera_pose(np.random.default_rng(0), cabinet)
    render(boxes, D415_640X480, T)
    best = min(_timed(lambda: render(boxes, D415_640X480, T)) for _ in range(3))
    assert best < 0.25  # about 45 ms on 2 cores; the bound catches an order-of-magnitude regression


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


# ---- cabinets ----


@pytest.mark.parametrize("hinge_right", [True, False])
def test_door_turns_about_its_true_axis(hinge_right):
    cabinet = SyntheticCabinet(kind="door", hinge_right=hinge_right, yaw_rad=2.9, position=(0.7, 0.1, 0.3))
    axis = cabinet.true_axis()
    assert axis.joint_type == JointType.REVOLUTE
    assert np.linalg.norm(axis.direction) == pytest.approx(1.0)
    hinge_points = axis.origin + np.outer([0.0, 0.2, 0.5], axis.direction)
    closed = cabinet.moving_parts(0.0)
    normal = cabinet.T_base_cabinet[:3, 0]
    for q in (0.3, 1.0, 1.6):
        moved = cabinet.moving_parts(q)
        for (a, _), (b, _) in zip(closed, moved, strict=True):
            M = rigid_motion(a, b)
            np.testing.assert_allclose(hinge_points @ M[:3, :3].T + M[:3, 3], hinge_points, atol=1e-9)
        turn = Rotation.from_rotvec(axis.direction * q).as_matrix()
        h0, hq = cabinet.handle_pose(0.0), cabinet.handle_pose(q)
        np.testing.assert_allclose(hq[:3, 3], axis.origin + turn @ (h0[:3, 3] - axis.origin), atol=1e-9)
        np.testing.assert_allclose(hq[:3, :3], turn @ h0[:3, :3], atol=1e-9)
        assert (hq[:3, 3] - h0[:3, 3]) @ normal > 0  # positive q opens
        M = rigid_motion(closed[0][0], moved[0][0])  # the handle moves rigidly with the door
        np.testing.assert_allclose(M @ h0, hq, atol=1e-9)


def test_drawer_handle_moves_along_the_axis_by_q():
    cabinet = SyntheticCabinet(kind="drawer", yaw_rad=3.3, position=(0.8, -0.2, 0.0))
    axis = cabinet.true_axis()
    assert axis.joint_type == JointType.PRISMATIC
    np.testing.assert_allclose(axis.direction, cabinet.T_base_cabinet[:3, 0])
    h0 = cabinet.handle_pose(0.0)
    assert (h0[:3, 3] - axis.origin) @ axis.direction == pytest.approx(cabinet.handle_standoff_m)
    for q in (0.05, 0.2, 0.35):
        hq = cabinet.handle_pose(q)
        np.testing.assert_allclose(hq[:3, 3] - h0[:3, 3], q * axis.direction, atol=1e-12)
        np.testing.assert_allclose(hq[:3, :3], h0[:3, :3])
        for (a, _), (b, _) in zip(cabinet.moving_parts(0.0), cabinet.moving_parts(q), strict=True):
            np.testing.assert_allclose(b.center - a.center, q * axis.direction, atol=1e-12)


@pytest.mark.parametrize("kind", ["drawer", "door"])
def test_grasp_frame_sits_on_the_bar_and_points_into_the_front(kind):
    for seed in range(5):
        cabinet = SyntheticCabinet.random(np.random.default_rng(seed), kind)
        T = cabinet.handle_pose(0.4)
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        parts = cabinet.moving_parts(0.4)
        handle = [b for b, label in parts if label == SegLabel.HANDLE]
        panels = [b for b, label in parts if label == SegLabel.OBJECT]
        assert inside_any(T[:3, 3][None], handle, 1e-9)[0]  # origin on the bar
        front = T[:3, 3] + (cabinet.handle_standoff_m + 0.002) * R[:, 2]  # z: approach into the front
        assert inside_any(front[None], panels, 1e-9)[0]
        if cabinet.handle_vertical:
            np.testing.assert_allclose(np.abs(R[:, 0]), [0, 0, 1], atol=1e-12)


@pytest.mark.parametrize("kind", ["drawer", "door"])
def test_random_cabinets_stay_in_their_ranges(kind):
    rng = np.random.default_rng(1)
    cabinets = [SyntheticCabinet.random(rng, kind) for _ in range(40)]
    for c in cabinets:
        assert 0.3 <= c.width_m <= 0.8 and 0.3 <= c.height_m <= 0.9 and 0.3 <= c.depth_m <= 0.5
        assert 0.6 <= np.hypot(*c.position[:2]) <= 0.9
        assert c.T_base_cabinet[:3, 0] @ -np.array([*c.position[:2], 0.0]) > 0  # the front faces the base
    assert len({c.hinge_right for c in cabinets}) == 2
    assert len({c.position[2] == 0 for c in cabinets}) == 2  # floor and table


def test_invalid_cabinet_raises():
    with pytest.raises(ValueError, match="drawer' or 'door"):
        SyntheticCabinet(kind="window")
    with pytest.raises(ValueError, match="too small"):
        SyntheticCabinet(kind="door", width_m=0.05)


# ---- sequences ----


def test_camera_pose_is_a_tripod_beside_and_above_framing_the_cabinet():
    for seed in range(20):
        rng = np.random.default_rng(seed)
        cabinet = SyntheticCabinet.random(rng, "door")
        T = random_camera_pose(rng, cabinet, D415_640X480)
        R, normal = cabinet.T_base_cabinet[:3, :3], cabinet.T_base_cabinet[:3, 0]
        center = R @ np.array([-cabinet.depth_m / 2, 0.0, cabinet.height_m / 2]) + cabinet.T_base_cabinet[:3, 3]
        front = center + cabinet.depth_m / 2 * normal
        offset = T[:3, 3] - front
        assert 0.6 <= np.linalg.norm(offset) <= 3.0
        assert 15 - 1e-9 <= np.degrees(np.arccos(offset @ normal / np.linalg.norm(offset))) <= 35 + 1e-9
        assert offset[2] > 0
        view = center - T[:3, 3]
        np.testing.assert_allclose(T[:3, 2], view / np.linalg.norm(view), atol=1e-12)  # looks at the centre
        assert T[:3, 0] @ [0, 0, 1] == pytest.approx(0.0, abs=1e-12)  # no roll
        np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)
        corners = np.vstack([box.corners() for box, _ in cabinet.body_parts()])
        cam = (corners - T[:3, 3]) @ T[:3, :3]
        u = D415_640X480.fx * cam[:, 0] / cam[:, 2] + D415_640X480.cx
        v = D415_640X480.fy * cam[:, 1] / cam[:, 2] + D415_640X480.cy
        assert np.all((u > 0) & (u < 640) & (v > 0) & (v < 480))  # the whole cabinet is in view
    with pytest.raises(ValueError, match="straight up or down"):
        look_at(np.array([0.0, 0.0, 2.0]), np.zeros(3))


@pytest.mark.parametrize("kind, travel", [("drawer", 0.25), ("door", 1.2)])
def test_sequence_mask_matches_the_object(kind, travel):
    rng = np.random.default_rng(4)
    seq = synthetic_sequence(kind, rng, travel, 4, noise=DepthNoise.none(), intrinsics=SMALL)
    assert len(seq.frames) == len(seq.gripper_poses) == 4
    np.testing.assert_allclose(seq.joint_values, np.linspace(0, travel, 4))
    for frame, q in zip(seq.frames, seq.joint_values, strict=True):
        assert frame.intrinsics == SMALL and frame.segmentation is not None
        object_labels = np.isin(frame.segmentation, [SegLabel.OBJECT, SegLabel.HANDLE])
        np.testing.assert_array_equal(frame.mask, object_labels)
        cabinet_boxes = [b for b, _ in seq.cabinet.parts(q)]
        on_object = pixel_points(np.where(frame.mask, frame.depth_m, 0), SMALL, frame.T_base_camera)
        elsewhere = pixel_points(np.where(frame.mask, 0, frame.depth_m), SMALL, frame.T_base_camera)
        assert len(on_object) > 500 and inside_any(on_object, cabinet_boxes, 1e-4).all()
        assert not inside_any(elsewhere, cabinet_boxes, -1e-4).any()
    assert (seq.frames[0].segmentation == SegLabel.HANDLE).sum() > 5
    axis = seq.cabinet.true_axis()
    np.testing.assert_array_equal(seq.true_axis.origin, axis.origin)
    assert seq.kind == kind and seq.true_axis.joint_type == seq.cabinet.joint_type
    np.testing.assert_allclose(seq.gripper_poses[-1], seq.cabinet.handle_pose(travel))


def test_sequence_is_deterministic_and_noisy():
    def make(seed):
        rng = np.random.default_rng(seed)
        return synthetic_sequence("door", rng, 0.5, 2, intrinsics=SMALL, gripper_noise_m=0.002)

    a, b, c = make(7), make(7), make(8)
    assert a.cabinet == b.cabinet and a.cabinet != c.cabinet
    for fa, fb in zip(a.frames, b.frames, strict=True):
        np.testing.assert_array_equal(fa.depth_m, fb.depth_m)
        np.testing.assert_array_equal(fa.color, fb.color)
    np.testing.assert_array_equal(a.gripper_poses[1], b.gripper_poses[1])
    assert np.any(a.frames[0].depth_m[a.frames[0].mask] == 0)  # d415 noise by default: some holes
    error = a.gripper_poses[1][:3, 3] - a.cabinet.handle_pose(0.5)[:3, 3]
    assert 0 < np.linalg.norm(error) < 0.02


def test_write_sequence_round_trips(tmp_path):
    seq = synthetic_sequence("drawer", np.random.default_rng(2), 0.2, 3, intrinsics=SMALL)
    write_sequence(seq, tmp_path / "seq")
    rec = FramesRecording(tmp_path / "seq")
    assert len(rec) == 3 and rec.has_masks and rec.intrinsics == SMALL
    np.testing.assert_allclose(rec.T_base_camera, seq.T_base_camera)
    for i, original in enumerate(seq.frames):
        frame = rec.frame(i)
        np.testing.assert_array_equal(frame.color, original.color)
        np.testing.assert_array_equal(frame.mask, original.mask)
        assert np.max(np.abs(frame.depth_m - original.depth_m)) <= 0.0005 + 1e-6
        assert rec.records[i]["joint_positions"] == pytest.approx([seq.joint_values[i]])
        np.testing.assert_allclose(rec.records[i]["ee_pose"], seq.gripper_poses[i])
    truth = json.loads((tmp_path / "seq" / "truth.json").read_text())
    assert truth["joint_type"] == "prismatic"
    np.testing.assert_allclose(truth["origin"], seq.true_axis.origin)
    np.testing.assert_allclose(truth["direction"], seq.true_axis.direction)
    np.testing.assert_allclose(truth["joint_values"], seq.joint_values)


def test_varied_views_reach_head_on_and_far_side_views_above_the_floor():
    from deploy.synthetic.sequence import VARIED_VIEW

    angles = []
    for seed in range(30):
        rng = np.random.default_rng(seed)
        cabinet = SyntheticCabinet.random(rng, "drawer")
        T = random_camera_pose(rng, cabinet, D415_640X480, view=VARIED_VIEW)
        normal = cabinet.T_base_cabinet[:3, 0]
        center = cabinet.T_base_cabinet[:3, :3] @ np.array([-cabinet.depth_m / 2, 0.0, cabinet.height_m / 2])
        front = center + cabinet.T_base_cabinet[:3, 3] + cabinet.depth_m / 2 * normal
        offset = T[:3, 3] - front
        angles.append(np.degrees(np.arccos(offset @ normal / np.linalg.norm(offset))))
        assert T[2, 3] >= VARIED_VIEW.min_height_m
    assert min(angles) < 15 and max(angles) > 45  # beyond the standard view's 15-35 deg


def test_eased_openings_start_and_end_slowly():
    seq = synthetic_sequence("drawer", np.random.default_rng(0), 0.1, 5, noise=DepthNoise.none(), intrinsics=SMALL,
                             easing=True)
    np.testing.assert_allclose(seq.joint_values, [0.0, 0.015625, 0.05, 0.084375, 0.1])
