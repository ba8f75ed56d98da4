"""A door's handle held again with the hand turned back toward the robot where the arc runs out of reach
(deploy/control/door_regrasp.py, deploy/control/out_of_reach.py `regrasp_turned`)."""

import numpy as np
import pytest

import deploy.control.stages as stages
from deploy.bench.open import simulate_episode
from deploy.control.door_regrasp import (
    closing_push_n,
    door_meets_hand,
    door_plane,
    held_as,
    held_centre,
    opening_direction,
)
from deploy.control.grasp import Handle, grasp_pose
from deploy.control.state import StopReason
from deploy.geometry.clearance import parallel_gripper
from deploy.geometry.types import Axis, JointType
from drivers.arm.motion import arc_path

UP = np.array([0.0, 0.0, 1.0])
NORMAL = np.array([-1.0, 0.0, 0.0])  # a front facing the robot, hinged on the robot's right
HANDLE = Handle(np.array([0.7, 0.0, 0.6]), NORMAL, UP.copy(), 0, "bar")
HINGE = Axis(JointType.REVOLUTE, np.array([0.72, -0.4, 0.6]), UP.copy(), confidence=0.0)  # opening: toward the robot
OPENED = np.radians(60.0)

# Test kitchen door 15 (70 deg): a knob whose arc, the hand turning with the door, runs the elbow (joint 4) onto its
# speed limit at 68 deg.
FAR_ARC_SEED = 15
# Test kitchen door 93 (70 deg): a vertical bar on a self-closing hinge whose arc runs out of reach at 67 deg; let go
# for the turned re-grasp, it swings shut.
SPRING_SEED = 93


def _yaw_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The turn (deg) about the vertical from horizontal direction a to b."""
    return float(np.degrees(np.arctan2(np.cross(a, b)[2], a @ b)))


def _held() -> np.ndarray:
    """The tool holding the handle after the door opened OPENED, turning with it."""
    return arc_path(grasp_pose(HANDLE), HINGE.origin, HINGE.direction)(OPENED)


def test_the_arm_holding_the_handle_tells_its_grip_centre():
    carried = arc_path(np.eye(4), HINGE.origin, HINGE.direction)(OPENED)[:3, :3] @ (HANDLE.center - HINGE.origin)
    assert held_centre(_held(), HANDLE) == pytest.approx(HINGE.origin + carried, abs=1e-9)


@pytest.mark.parametrize("pitch", [0.25, 0.0])
def test_the_handle_as_a_grasp_holds_it_gives_that_grasp_back(pitch):
    T = arc_path(grasp_pose(HANDLE, pitch_rad=pitch), HINGE.origin, HINGE.direction)(OPENED)
    assert grasp_pose(held_as(T, HANDLE), pitch_rad=pitch) == pytest.approx(T, abs=1e-9)


@pytest.mark.parametrize("yaw_deg", [15.0, 30.0, 45.0])
def test_swung_back_about_the_handle_the_hand_holds_the_same_grip_centre_nearer_the_closed_doors_normal(yaw_deg):
    centre = held_centre(_held(), HANDLE)
    swung = arc_path(_held(), centre, -HINGE.direction)(np.radians(yaw_deg))
    held = held_as(swung, HANDLE)
    carried = -_held()[:3, 2]
    carried[2] = 0.0
    assert _yaw_deg(NORMAL, carried) == pytest.approx(60.0)  # the door turned the hand 60 deg from facing the robot
    assert _yaw_deg(NORMAL, held.normal) == pytest.approx(60.0 - yaw_deg)
    assert held.center == pytest.approx(centre, abs=1e-9)
    assert held.bar @ UP == pytest.approx(_held()[:3, 0] @ UP)  # the vertical bar as upright between the fingers


def test_the_doors_plane_stands_turned_the_handles_relief_behind_its_grip_centre():
    centre = held_centre(_held(), HANDLE)
    origin, normal = door_plane(HANDLE, centre, HINGE, OPENED, 0.04)
    assert _yaw_deg(NORMAL, normal) == pytest.approx(60.0)
    assert (centre - origin) @ normal == pytest.approx(0.04)


@pytest.mark.parametrize("opened", [0.0, OPENED])
def test_the_handle_of_a_door_opening_toward_the_robot_moves_along_the_doors_outward_normal(opened):
    turn = arc_path(np.eye(4), HINGE.origin, HINGE.direction)(opened)
    centre = turn[:3, :3] @ (HANDLE.center - HINGE.origin) + HINGE.origin
    moving = opening_direction(HINGE, centre)
    assert np.linalg.norm(moving) == pytest.approx(1.0)
    assert moving @ (centre - HINGE.origin) == pytest.approx(0.0, abs=1e-9)  # across the lever, on the arc
    assert moving @ (turn[:3, :3] @ NORMAL) > np.cos(np.radians(5.0))  # the grip centre is 2 cm off the hinge's plane


@pytest.mark.parametrize("push_n, friction_n", [(8.0, 3.0), (0.0, 2.5), (2.0, 5.0)])
def test_friction_cancels_between_carrying_the_door_open_and_easing_it_closed(push_n, friction_n):
    # the hand holds the door back against its push and works against friction opening it, is helped closing it
    assert closing_push_n(push_n + friction_n, push_n - friction_n) == pytest.approx(push_n)


def test_a_door_arc_out_of_reach_goes_on_from_a_grasp_turned_back():
    result = simulate_episode("door", FAR_ARC_SEED, split="test", target=70.0)
    assert result["success"], result["message"]


def _no_shorter_steps(monkeypatch) -> None:
    """A step out of reach is not tried again shorter (`stages._shorter_door_step`): it ends the episode."""
    def out_of_reach(episode, axis, length, label, limits, error):
        raise error

    monkeypatch.setattr(stages, "_shorter_door_step", out_of_reach)


def test_without_turning_back_that_arc_ends_out_of_reach(monkeypatch):
    monkeypatch.setattr(stages, "MAX_TURNED_REGRASPS", 0)
    _no_shorter_steps(monkeypatch)
    result = simulate_episode("door", FAR_ARC_SEED, split="test", target=70.0)
    # the scenario does need the re-grasp: the test above is not vacuous
    assert result["stop_reason"] == StopReason.IK_INFEASIBLE, result["message"]
    assert result["true_opened_deg"] < 70.0


def test_a_self_closing_door_stays_held_while_the_hand_turns_back_about_its_bar():
    result = simulate_episode("door", SPRING_SEED, split="test", target=70.0)
    assert result["success"], result["message"]


TAB = Handle(np.array([0.7, 0.0, 0.6]), NORMAL, np.array([0.0, 1.0, 0.0]), 0, "edge pull")  # fingers close upright
TAB_RELIEF_M = 0.013


def _hand() -> tuple:
    return tuple(box for box in parallel_gripper(0.03, 0.08) if box.name == "hand")


@pytest.mark.parametrize("pitch", [0.25, 0.0])
def test_a_door_turning_against_a_hand_that_keeps_its_orientation_reaches_the_hand_only_far_open(pitch):
    T = grasp_pose(TAB, pitch_rad=pitch)
    for deg, meets in ((0.0, False), (20.0, False), (85.0, True)):
        kept = arc_path(T, HINGE.origin, HINGE.direction, turn=False)(np.radians(deg))
        assert door_meets_hand(kept, TAB, HINGE, np.radians(deg), TAB_RELIEF_M, 0.0, _hand()) is meets, deg
    turned = arc_path(T, HINGE.origin, HINGE.direction)(np.radians(85.0))  # the hand turned with the door
    assert not door_meets_hand(turned, TAB, HINGE, np.radians(85.0), TAB_RELIEF_M, 0.0, _hand())


# Test kitchen door 50 (70 deg): a tab turning between the pads; a hand that keeps its orientation meets the door's
# front past 64 deg, which pries the tab out of the fingers.
PALM_SEED = 50
# Test kitchen door 64 (70 deg): a handle whose steps 4 and 5, turned with the door to keep the front off the hand,
# need joint 2 past its limit.
TURN_OUT_OF_REACH_SEED = 64


@pytest.mark.parametrize("seed", [PALM_SEED, TURN_OUT_OF_REACH_SEED])
def test_a_door_kept_off_the_hand_stays_held_to_its_target(seed):
    result = simulate_episode("door", seed, split="test", target=70.0)
    assert result["success"], result["message"]


@pytest.mark.parametrize("seed, rule, stop", [(PALM_SEED, "_door_meets_hand", StopReason.GRASP_LOST),
                                              (TURN_OUT_OF_REACH_SEED, "_turned_for_hand", StopReason.IK_INFEASIBLE)])
def test_without_its_rule_that_door_is_lost(monkeypatch, seed, rule, stop):
    """The tests above are not vacuous: a hand that keeps its orientation loses door 50's tab; a turn with the door
    that does not give way to keeping the orientation ends door 64 out of reach."""
    monkeypatch.setattr(stages, rule, lambda *_: False)
    _no_shorter_steps(monkeypatch)
    result = simulate_episode("door", seed, split="test", target=70.0)
    assert result["stop_reason"] == stop, result["message"]


def test_a_long_bar_turning_between_the_pads_swings_its_end_into_the_hand():
    bar = Handle(TAB.center, NORMAL, TAB.bar, 0, "bar", depth_m=0.01)
    T = grasp_pose(bar)
    for deg, meets in ((20.0, False), (75.0, True)):
        kept = arc_path(T, HINGE.origin, HINGE.direction, turn=False)(np.radians(deg))
        assert door_meets_hand(kept, bar, HINGE, np.radians(deg), 0.03, 0.12, _hand()) is meets, deg
        assert not door_meets_hand(kept, bar, HINGE, np.radians(deg), 0.03, 0.0, _hand())  # its front alone: clear
