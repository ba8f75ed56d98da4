"""Drawer or door from the first pull (pure): a drawer's front translates, a door's front turns.

After a short straight pull the front face around the grip point is fitted again; its horizontal normal
turned by the door's opening angle (a 2.5 cm pull turns a 0.6 m wide door by ~2.4 deg) or stayed put (drawer).
A front that neither turned nor moved out resisted the straight pull: a hinge holds it (a drawer slides).
"""

from __future__ import annotations

import numpy as np

from deploy.control.grasp import front_normal
from deploy.geometry.types import Box, JointType

MIN_SHIFT_SHARE = 0.4  # a drawer's front moves out by at least this share of the probe pull
NEAR_HANDLE_M = 0.08  # the front's shift is measured on points this close to the handle, across the normal
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


def front_shift_m(points_before: np.ndarray, points_after: np.ndarray, handle: np.ndarray,
                  normal: np.ndarray) -> float:
    """How far (m) the front around the handle moved out along `normal`: the change of the median depth of
    the object points within NEAR_HANDLE_M of the handle across the normal (0 when either side is empty)."""
    def depth(points: np.ndarray) -> float | None:
        pts = np.asarray(points, float).reshape(-1, 3) - handle
        across = np.linalg.norm(pts - np.outer(pts @ normal, normal), axis=1)
        near = pts[across < NEAR_HANDLE_M] @ normal
        return float(np.median(near)) if len(near) else None

    before, after = depth(points_before), depth(points_after)
    return 0.0 if before is None or after is None else after - before


def classify_joint(turn_deg: float, shift_m: float, probe_m: float, min_turn_deg: float = MIN_TURN_DEG) -> JointType:
    """Revolute when the front turned by more than `min_turn_deg` or did not move out with the probe (held by
    a hinge); prismatic when it moved out at least MIN_SHIFT_SHARE of the probe without turning."""
    if turn_deg > min_turn_deg or shift_m < MIN_SHIFT_SHARE * probe_m:
        return JointType.REVOLUTE
    return JointType.PRISMATIC
