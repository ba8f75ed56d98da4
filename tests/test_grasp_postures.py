"""The grasp planner's arm postures: the usual elbow seeds for every grasp first, the elbow swung out sideways only
when they carry none as clear of the scene (a hand tilted up under a counter's overhang needs the wrist past its limit
from them)."""

from types import SimpleNamespace

import numpy as np
import pytest

import deploy.control.stages as stages
from deploy.control.grasp import HALF_TURN, Handle, grasp_pose, pregrasp_configuration
from deploy.control.out_of_reach import line_pulls
from deploy.geometry.types import JointType
from drivers.arm.grasping import GRASP_PITCH_RAD, LIMIT_MARGIN_RAD, pregrasp_pose
from drivers.arm.kinematics import Kinematics
from drivers.arm.robots import panda
from drivers.errors import IKError

NORMAL = np.array([-np.cos(0.16), -np.sin(0.16), 0.0])  # a drawer's front turned 0.16 rad, its bar 0.63 m out
BAR = Handle(np.array([0.595, 0.193, 0.736]), NORMAL, np.cross(NORMAL, [0.0, 0.0, 1.0]), 0, "bar")
PULL_M = 0.3


@pytest.fixture(scope="module")
def kin() -> Kinematics:
    return Kinematics.panda()


def _episode(kin: Kinematics) -> SimpleNamespace:
    """What `stages._grasp_plan` reads of an episode: a drawer pulled PULL_M from the arm's ready posture."""
    opening = SimpleNamespace(approach_m=0.1, target_distance_m=PULL_M - 0.015)
    return SimpleNamespace(observer=SimpleNamespace(pointed=object(), first_look=SimpleNamespace(frame=None)),
                           gripper=SimpleNamespace(max_opening_m=0.08), kin=kin,
                           config=SimpleNamespace(opening=opening),
                           arm=SimpleNamespace(state=lambda: SimpleNamespace(q=np.array(panda().q_ready))),
                           state=SimpleNamespace(joint=JointType.PRISMATIC))


def test_a_hand_tilted_up_is_carried_only_with_the_elbow_swung_out(kin):
    """Tilted up (from under an overhang) and pulled 0.3 m: every usual elbow seed needs joint 6 past its upper
    limit; swung out sideways, the arm reaches the pre-grasp pose within its limits."""
    T = grasp_pose(BAR, pitch_rad=-GRASP_PITCH_RAD)
    q_ready = np.array(panda().q_ready)
    with pytest.raises(IKError, match="out of reach"):
        pregrasp_configuration(kin, q_ready, T, line_pulls(T, NORMAL, PULL_M), 0.1)
    q = pregrasp_configuration(kin, q_ready, T, line_pulls(T, NORMAL, PULL_M), 0.1, swung=True)
    assert np.allclose(kin.fk(q), pregrasp_pose(T, 0.1), atol=1e-3)
    assert np.all(q > kin.q_min + LIMIT_MARGIN_RAD) and np.all(q < kin.q_max - LIMIT_MARGIN_RAD)


def test_every_grasp_is_tried_with_the_usual_postures_before_the_elbow_swings_out(kin, monkeypatch):
    """The clear grasps in order, tilted up first, both grazing the scene alike: the tilted-down one, which a usual
    posture carries, is planned before the tilted-up one with the elbow swung out; the tilted-up one alone is planned
    swung out."""
    up, down = grasp_pose(BAR, pitch_rad=-GRASP_PITCH_RAD), grasp_pose(BAR)
    monkeypatch.setattr(stages, "scene_tree", lambda frame, pointed: None)
    grasps = [(up, 0.08, True), (down, 0.08, True)]
    monkeypatch.setattr(stages, "ranked_grasps", lambda *args: grasps)
    episode = _episode(kin)
    T, _, q = stages._grasp_plan(episode, BAR)
    assert np.allclose(T, down)
    assert np.allclose(q, pregrasp_configuration(kin, episode.arm.state().q, down,
                                                 stages._planned_pulls(episode, BAR, down), 0.1))
    grasps.pop()
    T, _, q = stages._grasp_plan(episode, BAR)  # as found the swung-out elbow carries half the pull, turned half a
    # turn about its approach the whole of it
    assert np.allclose(T, up @ HALF_TURN) and np.allclose(kin.fk(q), pregrasp_pose(T, 0.1), atol=1e-3)


def test_a_grasp_clear_of_the_scene_swung_out_goes_before_a_grazing_one(kin, monkeypatch):
    """Tilted up, the hand keeps clear of a counter's overhang that the tilted-down hand grazes: the elbow swung out
    carries its whole pull (turned half a turn), so it goes before the grazing grasp a usual posture carries; with a
    pull longer than the swung-out arm carries whole, the grazing grasp is taken."""
    up, down = grasp_pose(BAR, pitch_rad=-GRASP_PITCH_RAD), grasp_pose(BAR)
    monkeypatch.setattr(stages, "scene_tree", lambda frame, pointed: None)
    monkeypatch.setattr(stages, "ranked_grasps", lambda *args: [(up, 0.08, False), (down, 0.08, True)])
    episode = _episode(kin)
    T, _, q = stages._grasp_plan(episode, BAR)
    assert np.allclose(T, up @ HALF_TURN) and np.allclose(kin.fk(q), pregrasp_pose(T, 0.1), atol=1e-3)
    episode.config.opening.target_distance_m = 0.6
    T, _, _ = stages._grasp_plan(episode, BAR)
    assert np.allclose(T, down)
