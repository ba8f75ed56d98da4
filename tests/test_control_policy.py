"""Pure decisions of the opening policy: handle, grasp pose, hinge prior, axis choice and opening."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deploy.config import Config, OpeningConfig
from deploy.control.grasp import (
    Handle,
    back_along_path,
    find_handle,
    grasp_pose,
    hinge_prior,
    hinge_side,
    hinge_side_sure,
    pointed_handle,
)
from deploy.control.policy import choose_axis, hinge_from_turn, holds_path, opening, orient_axis, seen_opening
from deploy.geometry.clearance import parallel_gripper
from deploy.geometry.types import Axis, Box, JointType, NoAxis
from deploy.perception.handle import Handle as PointedHandle
from deploy.policies import POLICIES, GrowingSteps, OpeningPolicy, opening_policy

# a cabinet whose front faces -x (toward a robot at the origin), front face at x = 0.5
BODY = Box(np.array([0.7, 0.0, 0.5]), np.eye(3), np.array([0.4, 0.6, 0.6]))
VIEW = np.array([0.0, 0.3, 1.0])


def _bar(vertical: bool, n: int = 200, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    along = rng.uniform(-0.06, 0.06, n)
    pts = np.zeros((n, 3))
    pts[:, 0] = 0.47 + rng.normal(0, 0.002, n)  # 3 cm in front of the face
    pts[:, 2 if vertical else 1] = along
    pts[:, 1 if vertical else 2] += rng.normal(0, 0.003, n)
    return pts + [0, 0.2, 0.6]


def _front(n: int = 2000) -> np.ndarray:
    """The front face (x = 0.5) and the top (z = 0.8) of the cabinet, noisy."""
    rng = np.random.default_rng(2)
    face = np.column_stack([0.5 + rng.normal(0, 0.001, n), rng.uniform(-0.3, 0.3, n), rng.uniform(0.2, 0.8, n)])
    top = np.column_stack([rng.uniform(0.5, 0.9, n // 2), rng.uniform(-0.3, 0.3, n // 2), np.full(n // 2, 0.8)])
    return np.vstack([face, top])


@pytest.mark.parametrize("vertical", [True, False])
def test_handle_and_grasp_pose(vertical):
    # the box is turned 20 deg: the front plane fitted near the handle wins
    turned = Box(BODY.center, Rotation.from_euler("z", 20, degrees=True).as_matrix(), BODY.extent)
    handle = find_handle(_bar(vertical), _front(), turned, VIEW, vertical_default=not vertical)
    np.testing.assert_allclose(handle.normal, [-1, 0, 0], atol=0.01)
    assert abs(abs(handle.bar[2 if vertical else 1]) - 1) < 0.01
    assert abs(handle.center[0] - (0.47 - 0.002 * 1.3 + 0.008)) < 0.002  # behind the front surface
    T = grasp_pose(handle)
    np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-9)
    assert T[0, 2] > 0.9 and T[2, 2] < 0  # approach into the front, tilted down
    assert abs(T[:3, 1] @ handle.bar) < 1e-6  # fingers across the bar


@pytest.mark.parametrize("clearance", [0.012, 0.018, 0.024])
def test_a_short_knob_is_held_with_the_fingers_short_of_the_front_behind_it(clearance):
    """A 2.7 cm knob whose centre stands `clearance` out of its door (front at x = 0.5): the tilted grasp's fingers
    (the leading corner of their tips, as the hand's collision boxes give them) stop at least the calibration's 5 mm
    short of the door, however near the front the knob sits; pressed on it, the arm stalled away from the knob."""
    centre = np.array([0.5 - clearance, 0.2, 0.6])
    knob = PointedHandle("protruding", "knob", centre, np.array([0, 0, 1.0]), np.array([0, 1.0, 0]),
                         np.array([-1.0, 0, 0]), 0.027, 0.027, clearance, clearance, 1.0, 0.0, "a knob", 0.08)
    handle = pointed_handle(knob, vertical_default=True)
    T = grasp_pose(handle)
    tips = next(box for box in parallel_gripper(0.08, 0.08) if box.name == "fingertips")
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * tips.half + tips.centre
    deepest = float((T[:3, :3] @ corners.T + T[:3, 3:4])[0].max())
    assert deepest <= 0.5 - 0.005 + 1e-9
    assert handle.depth_m >= -0.005 and (T[:3, 3] - centre) @ T[:3, 2] >= -0.005 - 1e-9  # the pads still reach it



@pytest.mark.parametrize(("length", "horizontal"), [(0.027, False), (0.033, False), (0.040, True)])
def test_a_knob_that_is_not_round_is_held_across_its_narrow_side(length, horizontal):
    """A door's knob-sized handle 19 mm tall (a cup half hidden by a neighbour reads 40 mm wide; a round knob seen at
    a slant from above reads up to 33 mm): a round one is held with the fingers closing level, one twice as wide as
    tall with them closing across its height (level, they pass beside its shell and close on nothing)."""
    knob = PointedHandle("pull", "knob", np.array([0.48, 0.2, 0.6]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]),
                         np.array([-1.0, 0, 0]), length, 0.019, 0.02, 0.02, 1.0, 0.0, "a knob", 0.08)
    handle = pointed_handle(knob, vertical_default=True)
    closing = grasp_pose(handle)[:3, 1]
    assert abs(closing[1]) < 1e-9 if horizontal else abs(closing[2]) < 1e-9  # across the shell, or level
    assert abs(abs(handle.bar[1 if horizontal else 2]) - 1) < 1e-9

def test_knob_and_empty_handle():
    knob = np.random.default_rng(1).normal([0.47, 0.2, 0.6], 0.005, (50, 3))
    handle = find_handle(knob, np.zeros((0, 3)), BODY, VIEW, vertical_default=True)  # no front: the box's
    np.testing.assert_allclose(handle.normal, [-1, 0, 0], atol=1e-9)
    assert abs(handle.bar[2]) > 0.99
    assert find_handle(np.zeros((2, 3)), _front(), BODY, VIEW, True) is None


def test_hinge_prior_is_the_far_edge_and_opens_outward():
    handle = Handle(np.array([0.47, 0.25, 0.6]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), 100)
    from_face = hinge_prior(handle, _front(), BODY)  # the face's far edge
    np.testing.assert_allclose(from_face.origin, [0.5, -0.3, 0.6], atol=0.015)
    from_box = hinge_prior(handle, np.zeros((0, 3)), BODY)  # no face points: the box's
    np.testing.assert_allclose(from_box.origin, [0.5, -0.3, 0.6], atol=1e-9)
    for prior in (from_face, from_box):  # a small positive rotation moves the handle out of the front (-x)
        assert np.cross(prior.direction, handle.center - prior.origin)[0] < 0


def _pair_pulled(hinge_y: float, handle_y: float, pulled: float) -> tuple[np.ndarray, np.ndarray]:
    """A pair of doors (front x = 0.5, y -0.3 to 0.3, meeting at y = 0), seen before and after the one hinged at
    `hinge_y` is pulled `pulled` straight out (-x) at `handle_y`: the same points (as the same pixels), each read with
    5 mm noise in 7 mm steps (a D415's at 1.5 m), a few pixels seeing another surface afterwards."""
    rng = np.random.default_rng(3)
    y, z = np.meshgrid(np.linspace(-0.3, 0.3, 121), np.linspace(0.3, 0.8, 51))
    before = np.column_stack([np.full(y.size, 0.5), y.ravel(), z.ravel()])
    radius = abs(handle_y - hinge_y)
    angle = np.arcsin(pulled / radius) * np.sign(handle_y - hinge_y)  # about +z: the door's side of the hinge
    moving = (before[:, 1] - 0.0) * np.sign(hinge_y) > 0
    hinge = np.array([0.5, hinge_y, 0.0])
    after = before.copy()
    after[moving] = Rotation.from_euler("z", angle).apply(before[moving] - hinge) + hinge
    for read in (before, after):
        read[:, 0] = np.round((read[:, 0] + rng.normal(0, 0.005, len(read))) / 0.007) * 0.007
    after[rng.choice(len(after), 40, replace=False), 0] -= 0.3  # a pixel that now sees the arm or another front
    return before, after


def test_a_handle_in_the_middle_of_its_front_leaves_the_hinge_side_to_how_the_front_moved():
    """A handle near one edge of the front (0.6 m wide, y -0.3 to 0.3) marks the other as the hinge; one in its middle
    third (a pair of doors taken for one front, a knob in the middle) does not: after a short straight pull the door
    moved out the less the nearer its hinge, and the prior takes the edge on that side."""
    near_edge = Handle(np.array([0.47, 0.25, 0.6]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), 100)
    assert hinge_side_sure(near_edge, _front(), BODY) and hinge_side_sure(near_edge, np.zeros((0, 3)), BODY)
    for hinge_y in (-0.3, 0.3):  # the handle on the other door of the pair, 5 cm from where they meet
        middle = Handle(np.array([0.47, -0.05 * np.sign(hinge_y), 0.6]), np.array([-1.0, 0, 0]),
                        np.array([0, 0, 1.0]), 100)
        assert not hinge_side_sure(middle, _front(), BODY) and not hinge_side_sure(middle, np.zeros((0, 3)), BODY)
        middle = replace(middle, center=np.array([0.47, 0.05 * np.sign(hinge_y), 0.6]))  # on the door that opens
        side = hinge_side(*_pair_pulled(hinge_y, middle.center[1], 0.025), middle, 0.025)
        assert side == np.sign(np.cross([0, 0, 1.0], middle.normal)[1] * hinge_y)
        prior = hinge_prior(middle, _front(), BODY, side=side)
        np.testing.assert_allclose(prior.origin, [0.5, hinge_y, 0.6], atol=0.015)
        assert np.cross(prior.direction, middle.center - prior.origin)[0] < 0  # opens out of the front
        still = _pair_pulled(hinge_y, middle.center[1], 0.025)[0]
        assert hinge_side(still, still, middle, 0.025) == 0.0  # nothing moved: no side
        assert hinge_prior(middle, _front(), BODY, side=0.0).origin[1] == pytest.approx(-hinge_y, abs=0.015)  # far


def test_opening_and_orientation():
    drawer = Axis(JointType.PRISMATIC, np.zeros(3), np.array([0.0, 1, 0]))
    assert opening(drawer, np.zeros(3), np.array([0.3, 0.2, 0.0])) == pytest.approx(0.2)
    assert orient_axis(drawer, np.array([0, -1.0, 0]), np.zeros(3)).direction[1] == -1
    door = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0, 0, 1.0]))
    start = np.array([0.4, 0, 0.2])
    c, s = np.cos(0.5), np.sin(0.5)
    assert opening(door, start, np.array([0.4 * c, 0.4 * s, 0.7])) == pytest.approx(0.5)
    flipped = orient_axis(door, np.array([0, -1.0, 0]), start)
    assert flipped.direction[2] == -1
    assert opening(door, start, start) == 0.0 and opening(door, np.zeros(3), start) == 0.0


def test_choose_axis_rule():  # openings in SI: rad for a door, m for a drawer
    cfg = OpeningConfig(task="door", fusion="fused")
    vision = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0, 0, 1.0]), confidence=0.5)
    traj = Axis(JointType.REVOLUTE, np.ones(3), np.array([0, 0, 1.0]), confidence=0.9)
    too_little = np.radians(5.0)  # for both
    assert choose_axis(vision, traj, JointType.REVOLUTE, too_little, cfg)[1] == "none"
    assert choose_axis(vision, traj, JointType.REVOLUTE, np.radians(20.0), cfg)[1] == "trajectory"
    vision_only = cfg.model_copy(update={"fusion": "vision"})
    assert choose_axis(vision, traj, JointType.REVOLUTE, np.radians(20.0), vision_only)[1] == "vision"
    loose = np.radians(19.0)  # the hinge's position is still loose
    assert choose_axis(vision, traj, JointType.REVOLUTE, loose, vision_only)[1] == "none"
    drawer = Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0, 0]), confidence=0.5)
    assert choose_axis(drawer, NoAxis("x"), JointType.PRISMATIC, 0.01, vision_only)[1] == "vision"
    fair_door = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0, 0, 1.0]), confidence=0.25)
    fair_drawer = Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0, 0]), confidence=0.25)
    assert choose_axis(fair_door, NoAxis("x"), JointType.REVOLUTE, np.radians(25.0), vision_only)[1] == "vision"
    assert choose_axis(fair_drawer, NoAxis("x"), JointType.PRISMATIC, 0.1, vision_only)[1] == "none"
    weak = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0, 0, 1.0]), confidence=0.01)
    result, source = choose_axis(weak, NoAxis("x"), JointType.REVOLUTE, np.radians(20.0), cfg)
    assert source == "none" and "confidence 0.01" in result.reason
    wrong = Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0, 0]), confidence=0.9)
    assert choose_axis(wrong, NoAxis("x"), JointType.REVOLUTE, np.radians(20.0), cfg)[1] == "none"


def test_config_targets_and_paper_schedule():
    cfg = OpeningConfig(task="door", target_angle_deg=45, policy="paper")
    assert cfg.target == pytest.approx(np.radians(45))
    paper = cfg.strategy()
    assert [paper.step_size(JointType.PRISMATIC, k, cfg) for k in (0, 1, 5)] == pytest.approx([0.10, 0.12, 0.16])
    assert paper.step_size(JointType.REVOLUTE, 10, cfg) == pytest.approx(0.15)
    with pytest.raises(ValueError, match="unknown policy 'sometimes': choose one of closed, open, paper"):
        OpeningConfig(policy="sometimes")


def test_each_policy_says_what_it_acts_with():
    opening = OpeningConfig(drawer_step_m=0.07, door_step_deg=10.0)
    closed, open_loop, paper = (opening_policy(name) for name in ("closed", "open", "paper"))
    assert (closed.re_estimates, open_loop.re_estimates, paper.re_estimates) == (True, False, True)
    assert closed.acting_estimator("screw") == "screw" and paper.acting_estimator("screw") == "paper-obb"
    assert closed.acting_fusion("force") == "force" and paper.acting_fusion("force") == "vision"
    assert not closed.straight_door(JointType.REVOLUTE) and paper.straight_door(JointType.REVOLUTE)
    assert not paper.straight_door(JointType.PRISMATIC)
    assert closed.step_size(JointType.PRISMATIC, 3, opening) == 0.07
    assert closed.step_size(JointType.REVOLUTE, 3, opening) == pytest.approx(np.radians(10.0))


def test_a_policy_registered_elsewhere_is_accepted_by_name(monkeypatch):
    """A new strategy needs its object and one registry line: the run config takes it and acts with what it says."""
    monkeypatch.setitem(POLICIES._entries, "cautious", None)  # removed again after the test
    POLICIES.register("cautious", f"{__name__}:_cautious", "closed loop on vision alone, small steps")
    config = Config().replace(opening={"policy": "cautious", "fusion": "force"}, estimator={"name": "screw"})
    assert config.opening.acting_fusion == "vision" and config.acting_estimator == "screw"
    assert config.opening.strategy().step_size(JointType.PRISMATIC, 0, config.opening) == 0.03


def _cautious(_argument: str) -> OpeningPolicy:
    return OpeningPolicy("cautious", None, "vision", re_estimates=True, door_arcs=True,
                         steps=GrowingSteps(drawer_m=(0.03, 0.03), door_m=(0.03, 0.03), grow_m=0.0))


def test_seen_opening_is_the_drawer_fronts_distance_out_of_the_cabinet_front():
    """The front faces (the densest outermost layers) are compared, not the handle standing 4 cm out."""
    rng = np.random.default_rng(0)
    direction = np.array([-0.8, 0.6, 0.0])  # the drawer opens toward the robot
    lateral = np.cross([0, 0, 1.0], direction)

    def plate(offset_m, n, half_width=0.2):
        return (offset_m * direction + np.outer(rng.uniform(-half_width, half_width, n), lateral)
                + np.outer(rng.uniform(0.3, 0.5, n), [0, 0, 1.0]) + rng.normal(0, 0.001, (n, 3)))

    first = np.vstack([plate(0.0, 5000), plate(0.04, 300, 0.05)])  # cabinet front + handle
    moving = np.vstack([plate(0.123, 3000), plate(0.163, 200, 0.05), plate(0.05, 1000)])  # front, handle, a side
    assert seen_opening(moving, first, 3.0 * direction) == pytest.approx(0.123, abs=0.003)  # any length
    assert seen_opening(moving[:150], first, direction) is None


def test_back_along_path_carries_the_held_point_back_to_where_the_part_started():
    """A slipped handle is looked for where the released part may have gone back: along the line, or on the arc."""
    door = Axis(JointType.REVOLUTE, np.array([0.3, -0.35, 0.9]), np.array([0.0, 0.0, 1.0]))
    closed = np.array([0.6, -0.35, 0.75])  # 0.3 m from the hinge
    held = door.origin + Rotation.from_rotvec([0, 0, np.radians(50)]).apply(closed - door.origin)
    points = back_along_path(door, held, np.radians(50), 0.12)
    assert np.allclose(points[0], held) and np.allclose(points[-1], closed)
    assert len(points) == 4  # 0.26 m of arc every 0.12 m or less
    assert all(np.linalg.norm((p - door.origin)[:2]) == pytest.approx(0.3) for p in points)
    assert np.linalg.norm(np.diff(points, axis=0), axis=1).max() <= 0.12
    assert opening(door, closed, points[1]) == pytest.approx(np.radians(50) * 2 / 3)

    drawer = Axis(JointType.PRISMATIC, np.zeros(3), np.array([-2.0, 0.0, 0.0]))  # any length
    points = back_along_path(drawer, np.array([0.3, 0.0, 0.5]), 0.25, 0.12)
    assert np.allclose(points, [[0.3, 0, 0.5], [0.3 + 0.25 / 3, 0, 0.5], [0.3 + 0.5 / 3, 0, 0.5], [0.55, 0, 0.5]])
    assert back_along_path(None, np.ones(3), 0.25, 0.12) == [pytest.approx(np.ones(3))]


def _swung_door(hinge: np.ndarray, grip: np.ndarray, normal: np.ndarray, turn_deg: float, slid_m: float):
    """A door hinged about the vertical through `hinge` (opening: the grip moves out along `normal`), turned by
    `turn_deg`: its front's normal then, and where the held grip is after sliding `slid_m` along the pads (the
    door's width)."""
    sign = np.sign(np.cross([0.0, 0.0, 1.0], grip - hinge) @ normal)
    R = Rotation.from_euler("z", sign * turn_deg, degrees=True).as_matrix()
    lateral = np.cross([0.0, 0.0, 1.0], normal)
    return R @ normal, hinge + R @ (grip - hinge) + slid_m * (R @ lateral)


@pytest.mark.parametrize("side", [1.0, -1.0])
@pytest.mark.parametrize("turn_deg, slid_m", [(8.0, 0.0), (25.0, 0.04), (40.0, -0.03)])
def test_a_door_hinge_from_its_front_turn_whatever_the_prior_radius_and_the_grip_slid(side, turn_deg, slid_m):
    # a 0.3 m door facing -x, the grip 4 cm proud of its front; the prior hinge on the front, on the other side
    normal, hinge = np.array([-1.0, 0.0, 0.0]), np.array([0.7, 0.3 * side, 0.65])
    grip = np.array([0.66, 0.0, 0.65])
    prior = Axis(JointType.REVOLUTE, np.array([0.7, -0.6 * side, 0.65]), np.array([0.0, 0.0, side]), confidence=0.0)
    turned, grip_now = _swung_door(hinge, grip, normal, turn_deg, slid_m)
    seen = hinge_from_turn(prior.origin, grip, grip_now, normal, turned, min_turn_deg=5.0)
    assert seen is not None and seen.joint_type is JointType.REVOLUTE
    np.testing.assert_allclose(seen.origin[:2], hinge[:2], atol=1e-6)
    assert opening(seen, grip, grip_now - slid_m * np.cross([0, 0, 1], turned)) == pytest.approx(np.radians(turn_deg))


def test_a_front_turned_too_little_places_no_hinge():
    normal, hinge, grip = np.array([-1.0, 0.0, 0.0]), np.array([0.7, 0.3, 0.65]), np.array([0.66, 0.0, 0.65])
    on_front = np.array([0.7, -0.3, 0.65])
    turned, grip_now = _swung_door(hinge, grip, normal, 3.0, 0.0)
    assert hinge_from_turn(on_front, grip, grip_now, normal, turned, min_turn_deg=5.0) is None
    assert hinge_from_turn(on_front, grip, grip_now, normal, np.array([0.0, 0.0, 1.0]), min_turn_deg=5.0) is None


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_front_seen_turned_the_other_way_keeps_the_hinge_placed_before(side):
    # a 0.3 m door facing -x, opened 20 deg and then 32: the first view of its turn placed the hinge; the second
    # sees another surface as the front, turned as much the other way round (the hinge would move past the grip)
    normal, hinge = np.array([-1.0, 0.0, 0.0]), np.array([0.7, 0.3 * side, 0.65])
    grip = np.array([0.66, 0.0, 0.65])
    turned, grip_now = _swung_door(hinge, grip, normal, 20.0, 0.0)
    placed = hinge_from_turn(hinge, grip, grip_now, normal, turned, min_turn_deg=5.0)
    assert placed is not None
    turned, grip_now = _swung_door(hinge, grip, normal, 32.0, 0.0)
    mirrored = turned * np.array([1.0, -1.0, 1.0])
    assert hinge_from_turn(hinge, grip, grip_now, normal, mirrored, 5.0, placed) is placed
    seen = hinge_from_turn(hinge, grip, grip_now, normal, turned, 5.0, placed)  # the front seen as it turned
    np.testing.assert_allclose(seen.origin[:2], hinge[:2], atol=1e-6)
    assert seen.direction @ placed.direction > 0


def test_a_hinge_fitted_nearer_the_grip_than_half_its_path_is_refused():
    # a 0.5 m door's grip pulled 5 cm straight out, then swung 25 deg: a circle of 8 cm radius does not hold that path
    hinge, grip = np.array([0.7, 0.5, 0.65]), np.array([0.66, 0.0, 0.65])
    straight = grip + np.outer(np.linspace(0.0, 0.05, 10), [-1.0, 0.0, 0.0])
    swing = Rotation.from_euler("z", -np.radians(np.linspace(0.0, 25.0, 30))[:, None])
    turns = swing.apply(straight[-1] - hinge) + hinge
    path = np.vstack([straight, turns])
    near = Axis(JointType.REVOLUTE, np.array([0.6, 0.1, 0.65]), np.array([0.0, 0.0, 1.0]), confidence=0.0,
                radius_m=0.08)
    true = Axis(JointType.REVOLUTE, hinge, np.array([0.0, 0.0, -1.0]), confidence=0.0, radius_m=0.5)
    assert not holds_path(near, path)
    assert holds_path(true, path)
    assert holds_path(Axis(JointType.PRISMATIC, grip, np.array([-1.0, 0.0, 0.0]), confidence=0.0), path)
    assert holds_path(NoAxis("no pull measured yet"), path)
