"""Drawer or door from the first pull (pure): a drawer's front translates, a door's front turns.

After a short straight pull the front face around the grip point is fitted again; its horizontal normal
turned by the door's opening angle (a 2.5 cm pull turns a 0.6 m wide door by ~2.4 deg) or stayed put (drawer).
"""

from __future__ import annotations

import numpy as np

from deploy.control.grasp import front_normal
from deploy.geometry.types import Box, JointType

MIN_TURN_DEG = 0.5  # revolute above this; measured after a 2.5 cm probe: drawers <= 0.08, doors 1.5-2.9 deg


def front_turn_deg(
    normal_before: np.ndarray, points_after: np.ndarray, grip_after: np.ndarray, body_box: Box,
    viewpoint: np.ndarray,
) -> float:
    """Angle (deg) between the front normal before the pull and the front face's normal around the grip
    point after it (object points of a later frame, base frame)."""
    normal_after = front_normal(points_after, grip_after, body_box, viewpoint)
    cos = float(np.clip(normal_before @ normal_after, -1.0, 1.0))
    return float(np.degrees(np.arccos(cos)))


def classify_joint(turn_deg: float, min_turn_deg: float = MIN_TURN_DEG) -> JointType:
    """Revolute when the front turned by more than `min_turn_deg`, else prismatic."""
    return JointType.REVOLUTE if turn_deg > min_turn_deg else JointType.PRISMATIC
