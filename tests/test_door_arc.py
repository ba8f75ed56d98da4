"""Whether a door's arc turns the tool with the door (deploy.control.hand.door_arc)."""

import numpy as np
import pytest

from deploy.control.hand import door_arc
from deploy.geometry.types import Axis, JointType
from drivers.arm.grasping import grasp_pose

NORMAL, UP = np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])  # a front facing the robot
HINGE = Axis(JointType.REVOLUTE, np.array([0.7, -0.4, 0.6]), UP.copy(), confidence=0.0)


def _turned_deg(T_start: np.ndarray, T_end: np.ndarray) -> float:
    cos = (np.trace(T_start[:3, :3].T @ T_end[:3, :3]) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


@pytest.mark.parametrize(("bar", "kind", "turns"), [
    (np.array([0.0, 1.0, 0.0]), "edge pull", False),  # a tab along the top edge: fingers close along the hinge
    (np.array([0.0, 1.0, 0.0]), "cup", False),
    (np.array([0.0, 1.0, 0.0]), "bar", False),
    (UP, "bar", True),  # a vertical bar: fingers close across the hinge, the hand's width in the swing
    (np.array([0.0, 1.0, 0.0]), "knob", True),  # its stem would swing into the fingers
    (np.array([0.0, 1.0, 0.0]), "recessed pull", True),  # the pocket's walls would
    (np.array([0.0, np.cos(0.7), np.sin(0.7)]), "cup", True),  # fingers closing 40 deg off the hinge: the door's turn
    # would twist the handle between the pads and swing its face into a finger
])
def test_a_handle_that_can_turn_between_the_pads_keeps_the_tool_orientation(bar, kind, turns):
    T = grasp_pose(np.array([0.7, 0.0, 0.6]), NORMAL, bar)
    end = door_arc(T, HINGE, kind)(np.radians(40))
    assert np.linalg.norm(end[:3, 3] - HINGE.origin) == pytest.approx(np.linalg.norm(T[:3, 3] - HINGE.origin))
    assert _turned_deg(T, end) == pytest.approx(40.0 if turns else 0.0, abs=1e-6)
