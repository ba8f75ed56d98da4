"""Drawer or door from the probe pull: how the front face around the grip point turned."""

import numpy as np
import pytest

from deploy.control.classify import classify_joint, front_shift_m, front_turn_deg
from deploy.geometry.types import Box, JointType

BODY = Box(np.array([0.7, 0.0, 0.5]), np.eye(3), np.array([0.4, 0.6, 0.6]))
VIEW = np.array([0.0, 0.3, 1.0])
FRONT = np.array([-1.0, 0.0, 0.0])  # the front faces the robot at the origin


def _panel(turn_deg: float, n: int = 3000, seed: int = 0) -> np.ndarray:
    """A door panel (x = 0.5 when closed) turned by `turn_deg` about a hinge at y = -0.3, with D415-like noise."""
    rng = np.random.default_rng(seed)
    y, z = rng.uniform(-0.3, 0.3, n), rng.uniform(0.2, 0.8, n)
    a = np.radians(turn_deg)
    lateral = y + 0.3
    pts = np.column_stack([0.5 - np.sin(a) * lateral, -0.3 + np.cos(a) * lateral, z])
    return pts + rng.normal(0.0, 0.0015, pts.shape)


@pytest.mark.parametrize("turn", [0.0, 1.5, 3.0])
def test_front_turn_is_measured(turn):
    grip = np.array([0.5, 0.2, 0.6])
    assert front_turn_deg(FRONT, _panel(turn), grip, BODY, VIEW) == pytest.approx(turn, abs=0.3)


def test_front_shift_follows_a_drawer_not_a_still_door():
    handle = np.array([0.47, 0.2, 0.6])
    closed = _panel(0.0)
    pulled = closed + [-0.025, 0.0, 0.0]  # the drawer front came 2.5 cm toward the robot
    assert front_shift_m(closed, pulled, handle, FRONT) == pytest.approx(0.025, abs=0.002)
    assert abs(front_shift_m(closed, _panel(0.0, seed=1), handle, FRONT)) < 0.002


def test_classify_rule():
    probe = 0.025
    assert classify_joint(0.08, 0.024, probe) is JointType.PRISMATIC  # a drawer's front after the probe
    assert classify_joint(1.5, 0.01, probe) is JointType.REVOLUTE  # the smallest door turn measured in simulation
    assert classify_joint(0.2, 0.001, probe) is JointType.REVOLUTE  # held still by a hinge: the probe slid
