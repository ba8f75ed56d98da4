"""The static-scene moving part and tracker (deploy/geometry/static_scene.py, deploy/perception/static_tracker.py) on
synthetic kitchen runs with the D415 depth model (tests/static_scenes.py): identical neighbouring fronts, a countertop,
a wall and a floor around the target."""

from dataclasses import replace

import cv2
import numpy as np
import pytest
from static_scenes import frame, scene, truth

from deploy.errors import PerceptionError
from deploy.geometry.static_scene import EDGE_REACH_PX, left_static, moving_pixels, opening_region, static_scene
from deploy.geometry.types import Box
from deploy.perception.static_tracker import StaticSceneTracker, front_region

DRAWER_OPENINGS = (0.02, 0.05, 0.10, 0.20, 0.30)
DOOR_OPENINGS = tuple(np.radians([5.0, 20.0, 45.0, 80.0]))


def reduced(mask: np.ndarray) -> np.ndarray:
    return mask[::2, ::2]


def beyond_edge(t: dict) -> np.ndarray:
    """Pixels farther than EDGE_REACH_PX from the part (closer ones may carry its depth: the D415 widens edges)."""
    distance = cv2.distanceTransform((~t["part"]).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return reduced(distance > EDGE_REACH_PX)


def started(kind: str) -> tuple[StaticSceneTracker, dict]:
    """A tracker started on the closed scene with the truth's front and furniture (the pointer's output)."""
    first = scene(kind, 0.0)
    t, f = truth(first), frame(first, seed=0)
    return StaticSceneTracker(f, t["furniture"], front_region(f, t["part"], 0.6)), t


def test_static_surfaces_never_leave_the_static_scene_under_d415_noise():
    """Twenty later frames of the unchanged scene, each with its own D415 noise: no pixel of the whole image stands
    in front of the first frame's static scene (no region)."""
    first = frame(scene("drawer", 0.0), seed=0)
    static = static_scene(first.depth_m, first.intrinsics.K, 2, first.T_base_camera)
    everywhere = Box(np.zeros(3), np.eye(3), np.full(3, 100.0))
    for seed in range(1, 21):
        later = frame(scene("drawer", 0.0), seed=seed)
        pixels, points = moving_pixels(static, later.depth_m, everywhere)
        assert not pixels.any() and len(points) == 0, seed


@pytest.mark.parametrize("kind, openings", [("drawer", DRAWER_OPENINGS), ("door", DOOR_OPENINGS)])
def test_identical_neighbouring_fronts_the_counter_wall_and_floor_never_count_as_moving(kind, openings):
    tracker, _ = started(kind)
    for k, opening in enumerate(openings, start=1):
        t = truth(scene(kind, opening))
        tracker.track(frame(scene(kind, opening), seed=k, index=k))
        wrong = tracker.moving & beyond_edge(t) & ~reduced(t["part"])
        assert not wrong.any(), (opening, int(wrong.sum()))
        assert not (tracker.moving & reduced(t["fronts"] | t["static"]) & beyond_edge(t)).any()


@pytest.mark.parametrize("kind, opening, recall", [("drawer", 0.10, 0.6), ("drawer", 0.30, 0.6),
                                                   ("door", np.radians(20.0), 0.6), ("door", np.radians(80.0), 0.9)])
def test_a_drawer_and_a_door_against_the_truth(kind, opening, recall):
    """Precision and recall of the moving part against the part's pixels: a drawer's inside seen through its open
    top lies behind where its front was (not counted), a door's surface near its hinge moves least."""
    tracker, _ = started(kind)
    later = frame(scene(kind, opening), seed=3, index=1)
    t = truth(scene(kind, opening))
    tracker.track(later)
    part = reduced(t["part"]) & (reduced(later.depth_m) > 0)
    assert (tracker.moving & part).sum() >= 0.97 * tracker.moving.sum()
    assert (tracker.moving & part).sum() >= recall * part.sum()


def test_the_inside_a_door_reveals_is_static():
    """The carcass's inside (shelf, back, sides) behind the open door is the furniture's, never the moving part's."""
    tracker, _ = started("door")
    for k, angle in enumerate(np.radians([30.0, 60.0, 90.0]), start=1):
        t = truth(scene("door", angle))
        later = frame(scene("door", angle), seed=k, index=k)
        mask = tracker.track(later)
        inside = reduced(t["furniture"] & ~t["part"] & (later.depth_m > 0)) & beyond_edge(t)
        assert inside.sum() > 500  # the opening door shows the inside
        assert not (tracker.moving & inside).any()
        assert reduced(mask)[inside].mean() > 0.9  # ... which the object mask keeps


@pytest.mark.parametrize("kind, opening", [("drawer", 0.15), ("door", np.radians(30.0))])
def test_the_arm_passing_in_front_neither_moves_the_part_nor_loses_it(kind, opening):
    """The arm's pixels (depth removed by the self-filter) are unknown: nothing behind them counts, nothing is lost
    around them, and once the arm has passed the mask is what it was."""
    tracker, _ = started(kind)
    closed = tracker.track(frame(scene(kind, 0.0), seed=1, index=1))
    hidden = frame(scene(kind, 0.0, arm=True), seed=2, index=2)
    assert not tracker.track(hidden)[hidden.depth_m == 0].any() and not tracker.moving.any()
    again = tracker.track(frame(scene(kind, 0.0), seed=3, index=3))
    assert (again & closed).sum() >= 0.97 * (again | closed).sum()
    t = truth(scene(kind, opening, arm=True))
    opened = frame(scene(kind, opening, arm=True), seed=4, index=4)
    tracker.track(opened)
    visible = reduced(t["part"]) & (reduced(opened.depth_m) > 0)
    assert not (tracker.moving & reduced(opened.depth_m == 0)).any()
    assert not (tracker.moving & beyond_edge(t) & ~reduced(t["part"])).any()
    assert (tracker.moving & visible).sum() >= 0.5 * visible.sum()


def test_a_hole_in_the_first_frame_is_the_surface_around_it():
    """Where the first frame had no depth (an IR shadow, a dark patch), a later reading of the same surface is static;
    something standing in front of the surfaces around the hole has left the static scene."""
    first = frame(scene("drawer", 0.0), seed=0)
    depth = first.depth_m.copy()
    depth[200:260, 300:360] = 0.0
    static = static_scene(depth, first.intrinsics.K, 2, first.T_base_camera)
    later = frame(scene("drawer", 0.0), seed=1).depth_m
    assert not left_static(static, later).any()
    nearer = later.copy()
    nearer[220:240, 320:340] = depth[190:270, 290:370][depth[190:270, 290:370] > 0].min() - 0.1
    assert left_static(static, nearer)[110:120, 160:170].all()


def test_the_camera_must_stay_where_it_was():
    tracker, _ = started("drawer")
    moved = frame(scene("drawer", 0.0), seed=1)
    pose = moved.T_base_camera.copy()
    pose[:3, 3] += [0.0, 0.01, 0.0]
    with pytest.raises(PerceptionError, match="camera moved.*fixed camera.*moving_part = \"box\""):
        tracker.track(replace(moved, T_base_camera=pose))
    with pytest.raises(PerceptionError, match="changed size"):
        tracker.track(replace(moved, depth_m=moved.depth_m[:240]))


def test_the_opening_region_sweeps_the_front_out_to_its_reach():
    front = Box(np.array([0.6, 0.0, 0.7]), np.eye(3), np.array([0.02, 0.4, 0.3]))  # a front facing -x
    region = opening_region(front, np.array([-1.0, 0.0, 0.0]), 0.5, behind_m=0.05, margin_m=0.03)
    inside = np.array([[0.59, 0.0, 0.7], [0.2, 0.2, 0.84], [0.64, -0.22, 0.56]])
    outside = np.array([[0.05, 0.0, 0.7], [0.7, 0.0, 0.7], [0.4, 0.25, 0.7], [0.4, 0.0, 0.9]])
    assert region.contains(inside).all() and not region.contains(outside).any()


def test_no_truth_reaches_the_tracker():
    """Frames carrying the simulator's labels and masks (garbage here) give the same masks as frames without."""
    first = scene("drawer", 0.0)
    t, f0 = truth(first), frame(first, seed=0)
    later = frame(scene("drawer", 0.2), seed=1, index=1)
    rng = np.random.default_rng(0)
    garbage = {"segmentation": rng.integers(0, 4, (480, 640), dtype=np.uint8), "mask": rng.random((480, 640)) > 0.5}
    masks = []
    for extra in ({}, garbage):
        tracker = StaticSceneTracker(replace(f0, **extra), t["furniture"], front_region(f0, t["part"], 0.6))
        masks.append(tracker.track(replace(later, **extra)))
    assert masks[0].any() and np.array_equal(masks[0], masks[1])


def test_todays_detector_followed_by_the_static_scene_never_takes_a_neighbour():
    """The rgbd detector takes the whole run (counter and neighbours with it); followed by the static scene, the
    opening drawer is still the only thing that moves."""
    from deploy.perception.rgbd import RGBDSegmenter
    from deploy.perception.static_tracker import StaticSceneSegmenter

    segmenter = StaticSceneSegmenter(RGBDSegmenter())
    first = segmenter.start(frame(scene("drawer", 0.0), seed=0))
    assert (first & truth(scene("drawer", 0.0))["fronts"]).any()  # the detection holds neighbours' fronts
    for k, opening in enumerate((0.1, 0.25), start=1):
        t = truth(scene("drawer", opening))
        mask = segmenter.track(frame(scene("drawer", opening), seed=k, index=k))
        moving = segmenter.tracker.moving
        assert (moving & reduced(t["part"])).sum() > 500
        assert not (moving & beyond_edge(t) & ~reduced(t["part"])).any()
        assert (mask & t["part"]).sum() >= 0.5 * t["part"].sum()


@pytest.mark.parametrize("kind, estimator", [("drawer", "screw-grip"), ("door", "screw-grip"), ("drawer", "screw")])
def test_the_pipeline_estimates_the_axis_from_the_static_scene(kind, estimator):
    """The axis pipeline's default moving part (static-scene, in the opening region of the pointed front) over an
    opening among identical neighbours: the axis within 2 deg; paper-obb keeps the paper's box cut."""
    from deploy.axis_pipeline import AxisPipeline
    from deploy.config import Config
    from deploy.geometry.metrics import axis_angle_error_deg
    from deploy.geometry.types import Axis

    config = Config().for_camera("sim").replace(estimator={"name": estimator, "joint": "auto"})
    tracker, t0 = started(kind)
    first = frame(scene(kind, 0.0), seed=0)
    pipe = AxisPipeline(config, region=tracker.region)
    assert pipe.static and not AxisPipeline(config.replace(estimator={"name": "paper-obb"})).static
    pipe.update_frame(first, t0["furniture"])
    openings = np.linspace(0.0, 0.25 if kind == "drawer" else np.radians(40.0), 11)[1:]
    for k, opening in enumerate(openings, start=1):
        later = frame(scene(kind, opening), seed=k, index=k)
        step = pipe.update_frame(later, tracker.track(later), gripper_pose(kind, opening))
    assert isinstance(step.result, Axis)
    true = np.array([-1.0, 0.0, 0.0]) if kind == "drawer" else np.array([0.0, 0.0, 1.0])
    assert axis_angle_error_deg(true, step.result.direction) < 2.0


def gripper_pose(kind: str, opening: float) -> np.ndarray:
    """The held handle's pose in the synthetic run (the arm's forward kinematics would give it)."""
    from static_scenes import FRONT_X, TARGET_Y, UNIT_W

    T = np.eye(4)
    if kind == "drawer":
        T[:3, 3] = [FRONT_X - 0.04 - opening, TARGET_Y + UNIT_W / 2, 0.78]
        return T
    c, s = np.cos(opening), np.sin(opening)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = np.array([FRONT_X - 0.02, TARGET_Y + 0.003, 0.58]) + T[:3, :3] @ [-0.039, UNIT_W - 0.056, 0.0]
    return T
