"""The opening policy's pure decisions: which axis to trust, how far the object is open (base frame, metres,
radians); its settings are `OpeningConfig` (deploy/config.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from deploy.config import OpeningConfig
from deploy.geometry.boxes import front_face_depth
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis


def orient_axis(axis: Axis, pull: np.ndarray, grip: np.ndarray) -> Axis:
    """The axis with its direction flipped if needed so that opening moves the grip point along `pull`
    (the front normal): drawer direction . pull > 0; door: (direction x (grip - origin)) . pull > 0."""
    if axis.joint_type is JointType.PRISMATIC:
        sign = np.sign(axis.direction @ pull)
    else:
        sign = np.sign(np.cross(axis.direction, grip - axis.origin) @ pull)
    if sign >= 0:
        return axis
    return replace(axis, direction=-axis.direction)


def opening(axis: Axis, p_start: np.ndarray, p_now: np.ndarray) -> float:
    """How far the grip point moved from `p_start` to `p_now` along the axis: metres along the line
    (prismatic) or radians about it (revolute, positive = opening)."""
    d = axis.direction / np.linalg.norm(axis.direction)
    if axis.joint_type is JointType.PRISMATIC:
        return float((p_now - p_start) @ d)
    a, b = p_start - axis.origin, p_now - axis.origin
    a, b = a - (a @ d) * d, b - (b @ d) * d
    if min(np.linalg.norm(a), np.linalg.norm(b)) < 1e-6:
        return 0.0
    return float(np.arctan2(np.cross(a, b) @ d, a @ b))


def hinge_from_turn(on_front: np.ndarray, grip_before: np.ndarray, grip_now: np.ndarray, normal_before: np.ndarray,
                    normal_now: np.ndarray, min_turn_deg: float, placed: Axis | None = None) -> Axis | None:
    """A door's hinge from how its front turned: the vertical line where the closed front's plane (through the point
    `on_front`, normal `normal_before`) meets the turned front's, which keeps the grip's depth in front of it
    (`grip_before` closed, `grip_now` with the front's normal `normal_now` as the camera sees it around the grip).
    Both planes hold the hinge, so the line needs no radius and no grip path (a handle may slide along the fingers'
    pads). Directed so that opening turns the grip out along `normal_before`; None when the front turned less than
    `min_turn_deg` (the planes meet too far off to tell). `placed`: the hinge an earlier view of the turn placed; a
    front seen turned the other way round, which puts the hinge on the grip's other side, is another surface taken
    for the front (a door opening turns one way), and `placed` stands."""
    n0, n1 = _horizontal(normal_before), _horizontal(normal_now)
    if n0 is None or n1 is None or np.degrees(np.arccos(np.clip(n0 @ n1, -1.0, 1.0))) < min_turn_deg:
        return None
    if placed is not None and np.cross(n0, n1)[2] * placed.direction[2] < 0:
        return placed
    grip_before, grip_now = np.asarray(grip_before, float), np.asarray(grip_now, float)
    proud = float(n0 @ (grip_before - on_front))  # the grip in front of the hinge's plane
    A = np.array([n0[:2], n1[:2]])
    b = np.array([n0 @ on_front, n1 @ grip_now - proud])
    origin = np.array([*np.linalg.solve(A, b), float(grip_now[2])])
    up = np.array([0.0, 0.0, 1.0])
    direction = up if np.cross(up, grip_before - origin) @ n0 >= 0 else -up
    return Axis(JointType.REVOLUTE, origin, direction, confidence=0.0)


def holds_path(axis: AxisResult, points: np.ndarray) -> bool:
    """Whether a hinge fitted to a grip's path (`points`, N x 3) can carry it: no two points of a circle of radius r
    lie farther apart than 2 r, so a path spread farther than that along its main direction does not lie on the
    fitted circle (a fit bent by a straight start reads the grip swung about a line beside it). True for any other
    axis."""
    if not isinstance(axis, Axis) or axis.joint_type is not JointType.REVOLUTE or axis.radius_m is None:
        return True
    centred = np.asarray(points, float) - np.mean(points, axis=0)
    spread = float(np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2][0]))
    return spread <= 2.0 * axis.radius_m


def _horizontal(v: np.ndarray) -> np.ndarray | None:
    """`v` without its vertical part, unit; None when it is vertical."""
    h = np.array([v[0], v[1], 0.0], float)
    size = float(np.linalg.norm(h))
    return h / size if size > 1e-6 else None


def choose_axis(
    vision: AxisResult, trajectory: AxisResult, joint: JointType | None, moved: float, config: OpeningConfig,
    strained: bool = False,
) -> tuple[AxisResult, str]:
    """The axis to act on and where it came from ("vision" | "trajectory" | "trajectory (force)" | "none").

    `moved` is the opening so far (m or rad, by the joint type); `strained`: the last pull was resisted across
    its path by `force_cue_n` or more. Rule ("fused"): the trajectory fit when it has the expected joint type,
    moved >= the trajectory minimum and confidence >= the minimum; vision otherwise. "force": the trajectory
    fit of the expected type when strained and moved >= the minimum (the compliant path followed the object
    where the commanded axis was off), vision otherwise. "trajectory" drops the gates; "vision" never uses it.
    The rule is `config.acting_fusion` (the paper's policy acts on vision alone).
    """
    fusion = config.acting_fusion
    expected = joint if joint is not None else (vision.joint_type if isinstance(vision, Axis) else None)
    use_trajectory = (
        fusion != "vision"
        and isinstance(trajectory, Axis)
        and (expected is None or trajectory.joint_type is expected)
    )
    if use_trajectory and fusion in ("fused", "force"):
        min_travel = (config.trajectory_min_travel_m if trajectory.joint_type is JointType.PRISMATIC
                      else np.radians(config.trajectory_min_travel_deg))
        confident = strained if fusion == "force" else \
            trajectory.confidence >= config.trajectory_min_confidence
        use_trajectory = moved >= min_travel and confident
    if use_trajectory:
        return trajectory, "trajectory (force)" if fusion == "force" else "trajectory"
    door = isinstance(vision, Axis) and vision.joint_type is JointType.REVOLUTE
    min_confidence = config.door_vision_min_confidence if door else config.vision_min_confidence
    if isinstance(vision, Axis) and (joint is None or vision.joint_type is joint) \
            and vision.confidence >= min_confidence and (not door or moved >= np.radians(config.vision_min_travel_deg)):
        return vision, "vision"
    reason = vision.reason if isinstance(vision, NoAxis) else (
        f"vision: {vision.joint_type.value} joint, confidence {vision.confidence:.2f}")
    return NoAxis(reason), "none"


def seen_opening(moving: np.ndarray, first_points: np.ndarray, direction: np.ndarray,
                 min_points: int = 200) -> float | None:
    """How far a drawer's front stands out of the cabinet's front, as the camera sees it (m): the front
    face of the moving part minus that of the first frame's object, along the drawer's `direction`
    (`front_face_depth`). None with fewer than `min_points` moving points."""
    moving = np.asarray(moving, float).reshape(-1, 3)
    if len(moving) < min_points or len(first_points) < min_points:
        return None
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return front_face_depth(moving @ d) - front_face_depth(np.asarray(first_points, float) @ d)
