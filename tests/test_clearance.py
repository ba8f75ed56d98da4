"""The gripper's clearance from the scene the first frame showed: the gripper model holds what the Panda's collision
meshes occupy, a path is checked between its poses, so a thin surface (a counter's front face) it passes through is
found, and a finger dipping behind the fronts' plane is."""

from dataclasses import replace
from itertools import combinations
from pathlib import Path

import numpy as np
import pybullet_data
import pytest
from scipy.spatial import cKDTree

from deploy.control.grasp import Handle, grasp_pose, grip_depth_m
from deploy.control.scene_clearance import Scene, clear_grasps, ranked_grasps
from deploy.control.state import EpisodeStop
from deploy.geometry.clearance import (
    clearance,
    depth_behind,
    first_behind,
    first_contact,
    parallel_gripper,
    swept_poses,
)
from drivers.arm.grasping import pregrasp_pose

MESHES = Path(pybullet_data.getDataPath()) / "franka_panda" / "meshes" / "collision"
HAND_TO_TOOL_M, HAND_TO_FINGER_M = 0.105, 0.0584  # panda.urdf: the grasp target and the finger joints on the hand
GRAZE_M = -0.005  # the clearance the grasp planner uses


def _vertices(name: str) -> np.ndarray:
    return np.array([[float(v) for v in line.split()[1:4]] for line in (MESHES / f"{name}.obj").read_text()
                     .splitlines() if line.startswith("v ")])


def _hull_points(vertices: np.ndarray) -> np.ndarray:
    """Points along every segment between two vertices: inside the convex hull, its edges among them."""
    pairs = np.array(list(combinations(range(len(vertices)), 2)))
    f = np.linspace(0.0, 1.0, 6)[:, None, None]
    return (vertices[pairs[:, 0]] * (1 - f) + vertices[pairs[:, 1]] * f).reshape(-1, 3)


def _outside(points: np.ndarray, boxes) -> float:
    """How far the point farthest from every box lies outside them (m)."""
    gaps = [np.linalg.norm(np.maximum(np.abs(points - b.centre) - b.half, 0.0), axis=1) for b in boxes]
    return float(np.min(gaps, axis=0).max())


def test_the_gripper_model_holds_the_pandas_collision_hulls():
    hand, finger = _hull_points(_vertices("hand")), _hull_points(_vertices("finger"))
    for opening in (0.0, 0.04, 0.08):
        left = finger + [0.0, opening / 2, HAND_TO_FINGER_M]
        right = finger * [-1.0, -1.0, 1.0] + [0.0, -opening / 2, HAND_TO_FINGER_M]  # the right finger turned half
        gripper = np.vstack([hand, left, right]) - [0.0, 0.0, HAND_TO_TOOL_M]
        assert _outside(gripper, parallel_gripper(opening, 0.08)) < 0.001, opening


def _counter_face(bottom_m: float) -> cKDTree:
    """A countertop's front face 4 cm out of the fronts' plane (x 0.785) and its top, as the camera sees them."""
    y, z = np.meshgrid(np.arange(-0.3, 0.3, 0.005), np.arange(bottom_m, 0.825, 0.005))
    face = np.column_stack([np.full(y.size, 0.745), y.ravel(), z.ravel()])
    y, x = np.meshgrid(np.arange(-0.3, 0.3, 0.005), np.arange(0.745, 0.9, 0.005))
    top = np.column_stack([x.ravel(), y.ravel(), np.full(y.size, 0.825)])
    return cKDTree(np.vstack([face, top]))


def _level_grasp(height_m: float) -> np.ndarray:
    """Approaching along +x at `height_m`, the fingers closing vertically, 1 cm short of the fronts' plane."""
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    T[:3, 3] = [0.775, 0.0, height_m]
    return T


def test_fingers_passing_through_a_counters_front_face_touch_it_however_coarse_the_path():
    T = _level_grasp(0.752)  # a tab on the door's top edge, 4.5 cm under the counter
    approach = [pregrasp_pose(T, 0.1 - 0.02 * k) for k in range(6)]  # every 2 cm: each pose clear by itself
    fully_open = parallel_gripper(0.08, 0.08)
    assert all(first_contact(_counter_face(0.797), [P], fully_open, GRAZE_M) is None for P in approach)
    touch = first_contact(_counter_face(0.797), approach, fully_open, GRAZE_M)
    assert touch is not None and touch.box.startswith("finger") and touch.point[2] < 0.81
    assert first_contact(_counter_face(0.797), approach[::5], fully_open, GRAZE_M) is not None  # the ends alone
    narrow = parallel_gripper(0.041, 0.08)  # opened only as wide as the tab needs: the fingers pass under it
    assert first_contact(_counter_face(0.80), approach[::5], narrow, GRAZE_M) is None


def test_a_path_is_checked_finely_enough_through_turns_and_moves():
    a = _level_grasp(0.5)
    b = a.copy()
    turn = np.radians(30.0)
    b[:3, :3] = np.array([[np.cos(turn), -np.sin(turn), 0.0], [np.sin(turn), np.cos(turn), 0.0], [0, 0, 1]]) @ a[:3, :3]
    b[:3, 3] += [0.05, 0.02, 0.0]
    poses = swept_poses([a, b], 0.005, 0.15)
    assert np.allclose(poses[0], a) and np.allclose(poses[-1], b)
    reach = np.array([[0.0, 0.15, 0.0, 1.0], [0.0, 0.0, -0.15, 1.0], [0.15, 0.0, 0.0, 1.0]]).T  # tool-frame points
    moves = [np.linalg.norm((Q @ reach - P @ reach)[:3], axis=0).max()
             for P, Q in zip(poses[:-1], poses[1:], strict=True)]
    assert max(moves) <= 0.005 + 1e-9 and len(poses) > 20


def test_a_tilted_finger_dipping_behind_the_fronts_plane_is_refused_and_the_level_grasp_taken():
    """A cup 1.5 cm out of its front: tilted down, the upper finger's far corner reaches behind the front (the scene
    leaves the fronts' plane out, the plane stands for it); held level, the fingers stay in front of it."""
    normal = np.array([-1.0, 0.0, 0.0])
    scene = Scene(cKDTree(np.array([[0.0, 0.0, 0.0]])), np.array([0.8, 0.0, 0.6]), normal)
    cup = Handle(np.array([0.785, 0.0, 0.6]), normal, np.array([0.0, 1.0, 0.0]), 100, "cup", open_m=0.08,
                 thickness_m=0.03, depth_m=0.008)
    grasps = clear_grasps(cup, scene, lambda T: [[T]], 0.1, 0.08)
    assert [opening for _, opening in grasps] == [0.08, 0.06]
    assert all(abs(T[2, 2]) < 1e-9 for T, _ in grasps)  # level: the approach has no downward tilt
    tilted = grasp_pose(cup)
    corner = first_behind([tilted], parallel_gripper(0.08, 0.08), scene.origin, normal, 0.01)
    assert corner is not None and corner.point[2] > 0.6 and corner.point[0] > 0.81  # above the cup, behind


def test_a_recessed_pull_under_a_counters_overhang_is_held_tilted_up_or_at_its_lip():
    """A pocket 8 cm under a counter whose front face stands 3 cm out of the fronts' plane: going in level as deep as
    the pocket lets it, the hand (21 cm along the fingers' closing direction) meets the counter's face; tilted up, the
    hand's upper edge leans out from it; with the pads' middle on the lip, the hand stays in front of it."""
    normal = np.array([-1.0, 0.0, 0.0])
    y, z = np.meshgrid(np.arange(-0.3, 0.3, 0.005), np.arange(0.78, 0.82, 0.005))
    counter = np.column_stack([np.full(y.size, 0.755), y.ravel(), z.ravel()])
    scene = Scene(cKDTree(counter), np.array([0.785, 0.0, 0.7]), normal)
    pull = Handle(np.array([0.795, 0.0, 0.7]), normal, np.array([0.0, 1.0, 0.0]), 0, "recessed pull", open_m=0.025,
                  depth_m=0.0087)

    def out_along_the_normal(T):
        poses = [T.copy() for _ in range(6)]
        for k, P in enumerate(poses):
            P[:3, 3] += 0.05 * (k + 1) * normal
        return [poses]

    (up, _), *rest = clear_grasps(pull, scene, out_along_the_normal, 0.1, 0.08)
    assert up[2, 2] > 0.2 and np.isclose((up[:3, 3] - pull.center) @ up[:3, 2], pull.depth_m)  # tilted up, deep
    assert rest and all(np.allclose(T[:3, 3], pull.center) for T, _ in rest)  # then the tool frame on the lip
    deep = grasp_pose(pull, pitch_rad=0.0)
    touch = first_contact(scene.points, [deep], parallel_gripper(0.025, 0.08), GRAZE_M)
    assert touch is not None and touch.box == "hand"
    tab = replace(pull, found="edge pull", center=np.array([0.767, 0.0, 0.7]), open_m=0.08, thickness_m=0.017,
                  depth_m=0.008)
    with pytest.raises(EpisodeStop):  # a tab's fingers would pass the counter's lower edge: only as deep as it asks
        clear_grasps(tab, Scene(cKDTree(counter - [0.0, 0.0, 0.05]), scene.origin, normal), out_along_the_normal, 0.1,
                     0.08)


def test_a_grasp_keeping_clear_of_the_scene_goes_before_one_grazing_it():
    """A bar 5 cm under a counter's lower edge, seen as a row of points: the usual grasp's upper finger, opened fully,
    grazes the edge (within the calibration's error, so not refused), and the edge's true line may lie up to the
    points' spacing lower; a grasp that keeps clear of it (narrower, level or tilted up) is taken first."""
    normal = np.array([-1.0, 0.0, 0.0])
    edge = np.column_stack([np.full(121, 0.78), np.linspace(-0.3, 0.3, 121), np.full(121, 0.754)])
    scene = Scene(cKDTree(edge), np.array([0.79, 0.0, 0.7]), normal)
    bar = Handle(np.array([0.76, 0.0, 0.7]), normal, np.array([0.0, 1.0, 0.0]), 0, "bar", open_m=0.08,
                 thickness_m=0.018)
    grasps = clear_grasps(bar, scene, lambda T: [[T]], 0.1, 0.08)
    usual = grasp_pose(bar)
    assert any(np.allclose(T, usual) and opening == 0.08 for T, opening in grasps)  # a graze is not refused
    first, opening = grasps[0]
    assert first_contact(scene.points, [pregrasp_pose(usual, 0.1), usual], parallel_gripper(0.08, 0.08), 0.0)
    assert first_contact(scene.points, [pregrasp_pose(first, 0.1), first], parallel_gripper(opening, 0.08),
                         0.01) is None


def test_a_grasp_keeping_in_front_of_the_fronts_plane_goes_before_one_dipping_a_finger_behind_it():
    """A rod 1.5 cm out of its front, the fingers opened 4 cm: tilted down, the upper finger's far corner reaches a few
    mm behind the front (within the plane's band, so not refused: it would press the front and hold that finger off
    the rod); level, the fingertips stay in front of it and that grasp is taken first."""
    normal = np.array([-1.0, 0.0, 0.0])
    scene = Scene(cKDTree(np.array([[0.0, 0.0, 0.0]])), np.array([0.8, 0.0, 0.6]), normal)
    rod = Handle(np.array([0.785, 0.0, 0.6]), normal, np.array([0.0, 1.0, 0.0]), 0, "bar", open_m=0.04,
                 thickness_m=0.01, depth_m=0.006)
    gripper = parallel_gripper(0.04, 0.08)
    tilted = grasp_pose(rod)
    assert first_behind([tilted], gripper, scene.origin, normal, 0.0) is not None
    assert first_behind([tilted], gripper, scene.origin, normal, 0.01) is None
    grasps = clear_grasps(rod, scene, lambda T: [[T]], 0.1, 0.08)
    assert any(np.allclose(T, tilted) for T, _ in grasps)
    first, opening = grasps[0]
    assert abs(first[2, 2]) < 1e-9 and first_behind([first], parallel_gripper(opening, 0.08), scene.origin, normal,
                                                     0.0) is None


def test_the_clearance_kept_is_the_nearest_points_distance_to_the_gripper_and_the_depth_behind_the_plane():
    T = _level_grasp(0.5)
    fingertips = parallel_gripper(0.04, 0.08)[0]  # 2.1 cm wide, reaching 0.7 cm past the tool frame
    tip = T[:3, 3] + T[:3, 2] * 0.007
    points = cKDTree(np.array([tip + [0.004, 0.0, 0.0], tip + [0.0, 0.0, 0.3]]))
    assert np.isclose(clearance(points, [T], (fingertips,), 0.01), 0.004)
    assert np.isclose(clearance(points, [pregrasp_pose(T, 0.1), T], (fingertips,), 0.01), 0.004)
    assert clearance(points, [pregrasp_pose(T, 0.1)], (fingertips,), 0.01) == 0.01
    assert np.isclose(depth_behind([T], (fingertips,), tip - [0.003, 0.0, 0.0], np.array([-1.0, 0.0, 0.0])), 0.003)
    assert depth_behind([T], (fingertips,), tip + [0.002, 0.0, 0.0], np.array([-1.0, 0.0, 0.0])) == 0.0


def test_along_a_doors_arc_the_grasps_keep_the_order_tried_though_a_finger_dips_within_the_planes_band():
    """The rod above on a door: its first planned pull is an arc about a hinge 40 cm to the side (the hand keeping
    its orientation, the rod turning between the pads), and there the grasps keep the order tried, the usual tilt
    down (which keeps the wrist off its limit) first; a straight pull from the same grasps puts the level one,
    keeping in front of the fronts' plane, first."""
    normal = np.array([-1.0, 0.0, 0.0])
    scene = Scene(cKDTree(np.array([[0.0, 0.0, 0.0]])), np.array([0.8, 0.0, 0.6]), normal)
    rod = Handle(np.array([0.785, 0.0, 0.6]), normal, np.array([0.0, 1.0, 0.0]), 0, "bar", open_m=0.04,
                 thickness_m=0.01, depth_m=0.006)
    hinge = np.array([0.8, 0.4, 0.6])

    def arc(T: np.ndarray) -> list[list[np.ndarray]]:
        poses = []
        for angle in np.radians([10.0, 20.0, 30.0]):
            c, s = np.cos(angle), np.sin(angle)
            R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            P = np.array(T, float)
            P[:3, 3] = hinge + R @ (P[:3, 3] - hinge)
            poses.append(P)
        return [poses]

    def straight(T: np.ndarray) -> list[list[np.ndarray]]:
        P = np.array(T, float)
        P[:3, 3] += 0.1 * normal
        return [[P]]

    (first, _), *_ = clear_grasps(rod, scene, arc, 0.1, 0.08)
    assert np.allclose(first, grasp_pose(rod))
    (first, _), *_ = clear_grasps(rod, scene, straight, 0.1, 0.08)
    assert abs(first[2, 2]) < 1e-9


def test_the_grasps_from_above_come_after_every_usual_grasp():
    """A bar 5 cm out of a low drawer with nothing around it: every usual grasp (tilted down, level, up, each finger
    opening) keeps clear and goes first, then those tilted steeply down (a low handle grasped from above) whose
    fingers keep in front of the fronts' plane (0.7 rad down; at 1.1 rad the lower finger's tip reaches behind it)."""
    normal = np.array([-1.0, 0.0, 0.0])
    scene = Scene(cKDTree(np.array([[0.0, 0.0, 0.0]])), np.array([0.8, 0.0, 0.4]), normal)
    bar = Handle(np.array([0.75, 0.0, 0.4]), normal, np.array([0.0, 1.0, 0.0]), 0, "bar", open_m=0.08,
                 thickness_m=0.018)
    pitches = [float(np.arcsin(-T[2, 2])) for T, _ in clear_grasps(bar, scene, lambda T: [[T]], 0.1, 0.08)]
    assert sorted(np.round(pitches[:6], 6)) == sorted(np.round([0.25, 0.0, -0.25] * 2, 6))
    assert np.allclose(pitches[6:], [0.7, 0.7])


def test_a_grasp_grazing_the_scene_goes_after_one_dipping_behind_the_fronts_plane():
    """A bar 1.1 cm out of its front, a counter's underside 10 cm above it reaching out to the fronts' plane: held
    level, the hand (21 cm along the fingers' closing direction) grazes the underside by 4 mm, which would hold it
    there as the handle is centred between the fingers; tilted up, its upper edge leans out from under it while the
    lower finger's corner dips 8 mm behind the fronts' plane (the front stops the compliant approach there): the
    tilted-up grasp goes first."""
    normal = np.array([-1.0, 0.0, 0.0])
    x, y = np.meshgrid(np.arange(0.70, 0.80, 0.005), np.arange(-0.3, 0.3, 0.005))
    underside = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 0.8)])
    scene = Scene(cKDTree(underside), np.array([0.80, 0.0, 0.7]), normal)
    bar = Handle(np.array([0.789, 0.0, 0.7]), normal, np.array([0.0, 1.0, 0.0]), 0, "bar", open_m=0.08,
                 thickness_m=0.017, depth_m=grip_depth_m(0.011, False))
    (up, opening, grazes), *rest = ranked_grasps(bar, scene, lambda T: [[T]], 0.1, 0.08)
    assert up[2, 2] > 0.2 and not grazes  # the approach tilted up
    assert first_behind([up], parallel_gripper(opening, 0.08), scene.origin, normal, 0.005) is not None
    assert rest and all(abs(T[2, 2]) < 1e-9 and grazes for T, _, grazes in rest)  # level, grazing
    level, level_opening, _ = rest[0]
    assert clearance(scene.points, [pregrasp_pose(level, 0.1), level], parallel_gripper(level_opening, 0.08), 0.01) < 0
