"""The opening policy's configuration and its pure decisions: which axis to trust, how far the object
is open, where the next step goes (base frame, metres, radians)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from deploy.geometry.boxes import front_face_depth
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis

Task = Literal["drawer", "door", "auto"]
Policy = Literal["closed", "open", "paper"]
Fusion = Literal["vision", "trajectory", "fused"]


class OpenConfig(BaseModel):
    """How to open: task, target (m for a drawer, deg for a door), policy, estimator and motion sizes.

    fusion: "vision" (default) uses the camera estimator only; "trajectory" the gripper's own path (FK)
    once it fits, vision before; "fused" the trajectory fit once the gripper has moved
    `trajectory_min_travel` (m or deg) and the fit is confident, vision otherwise and for the joint type.
    A vision estimate below `vision_min_confidence` is not acted on: the previous axis is kept, at first
    the prior from the first frame (drawer: the front normal; door: the front's far edge).
    Measured (16 test seeds, door 45 deg): vision 15/16, fused 11/16: the gripper follows the commanded
    arc, so its own path mostly re-fits the command and adds fit error; drawer 30 cm: 15/16 either way.
    A 0.1 confidence gate let 5-30 deg vision errors through (drawer 11/16). A door's vision axis after
    ~13 deg was 15 cm off on test seed 4 (joint auto): hence `vision_min_travel_deg`. Past it a door's
    vision axis rarely reaches 0.5 (its fit residual is 2-3 mm), so doors ran on the prior (about 2 cm off);
    at 0.2 (`door_vision_min_confidence`) door 70 test seeds 0-29 succeed as often (28/30). Since a door's
    body box reaches behind the front (2026-11-24), its vision confidence past 20 deg is mostly 0.3-0.95
    and the final hinge is 0.7-1.3 cm from the true one (median of 100 test episodes, docs/benchmarks.md).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    task: Task = "drawer"
    target_distance_m: float = Field(default=0.30, gt=0, le=1.0)
    target_angle_deg: float = Field(default=45.0, gt=0, le=170)
    policy: Policy = "closed"
    dry_run: bool = Field(default=False, description="perceive and plan the grasp, command nothing")
    estimator: Literal["screw", "screw-grip", "paper-obb", "trajectory"] = "screw"
    fusion: Fusion = "vision"
    window: int = Field(default=10, ge=2, le=100)
    first_pull_m: float = Field(default=0.05, gt=0, le=0.15)
    probe_pull_m: float = Field(default=0.025, gt=0, le=0.1, description="task auto: straight pull that classifies")
    drawer_step_m: float = Field(default=0.08, gt=0, le=0.3)
    door_step_deg: float = Field(default=12.0, gt=0, le=45)
    trajectory_min_travel_m: float = Field(default=0.05, gt=0)
    trajectory_min_travel_deg: float = Field(default=10.0, gt=0)
    trajectory_min_confidence: float = Field(default=0.5, ge=0, le=1)
    vision_min_confidence: float = Field(default=0.5, ge=0, le=1)
    door_vision_min_confidence: float = Field(default=0.2, ge=0, le=1)
    vision_min_travel_deg: float = Field(default=20.0, ge=0, description="a door's vision axis is acted on "
                                         "from this opening on: a small turn leaves the hinge's position loose")
    max_steps: int = Field(default=12, ge=1)
    timeout_s: float = Field(default=90.0, gt=0, description="arm-clock seconds for the whole episode")
    camera_hz: float = Field(default=5.0, gt=0, le=60)
    approach_m: float = Field(default=0.10, gt=0, le=0.3)
    pull_speed_m_s: float = Field(default=0.08, gt=0, le=0.5)
    pull_speed_deg_s: float = Field(default=12.0, gt=0, le=90)
    min_mask_fraction: float = Field(default=0.2, gt=0, lt=1, description="tracking lost below this")

    @property
    def target(self) -> float:
        """The target in the policy's units: metres (drawer) or radians (door)."""
        return self.target_distance_m if self.task != "door" else float(np.radians(self.target_angle_deg))

    def target_for(self, joint: JointType) -> float:
        return self.target_distance_m if joint is JointType.PRISMATIC else float(np.radians(self.target_angle_deg))

    def step_for(self, joint: JointType, k: int) -> float:
        """Step k (0-based) in m or rad; the paper's schedule grows 0.10 -> 0.16 m / 0.07 -> 0.15 rad-equivalents
        (metres of straight pull for both)."""
        if self.policy == "paper":
            start, end = (0.10, 0.16) if joint is JointType.PRISMATIC else (0.07, 0.15)
            return min(start + 0.02 * k, end)
        return self.drawer_step_m if joint is JointType.PRISMATIC else float(np.radians(self.door_step_deg))


def orient_axis(axis: Axis, pull: np.ndarray, grip: np.ndarray) -> Axis:
    """The axis with its direction flipped if needed so that opening moves the grip point along `pull`
    (the front normal): drawer direction . pull > 0; door: (direction x (grip - origin)) . pull > 0."""
    if axis.joint_type is JointType.PRISMATIC:
        sign = np.sign(axis.direction @ pull)
    else:
        sign = np.sign(np.cross(axis.direction, grip - axis.origin) @ pull)
    if sign >= 0:
        return axis
    return Axis(axis.joint_type, axis.origin, -axis.direction, axis.confidence, axis.residual_m, axis.radius_m)


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


def choose_axis(
    vision: AxisResult, trajectory: AxisResult, joint: JointType | None, moved: float, config: OpenConfig
) -> tuple[AxisResult, str]:
    """The axis to act on and where it came from ("vision" | "trajectory" | "none").

    `moved` is the opening so far (m or deg, by the joint type). Rule ("fused"): the trajectory fit
    when it has the expected joint type, moved >= the trajectory minimum and confidence >= the minimum;
    vision otherwise. "trajectory" drops the travel and confidence gates; "vision" never uses it.
    """
    expected = joint if joint is not None else (vision.joint_type if isinstance(vision, Axis) else None)
    use_trajectory = (
        config.fusion != "vision"
        and isinstance(trajectory, Axis)
        and (expected is None or trajectory.joint_type is expected)
    )
    if use_trajectory and config.fusion == "fused":
        min_travel = (config.trajectory_min_travel_m if trajectory.joint_type is JointType.PRISMATIC
                      else config.trajectory_min_travel_deg)
        use_trajectory = moved >= min_travel and trajectory.confidence >= config.trajectory_min_confidence
    if use_trajectory:
        return trajectory, "trajectory"
    door = isinstance(vision, Axis) and vision.joint_type is JointType.REVOLUTE
    min_confidence = config.door_vision_min_confidence if door else config.vision_min_confidence
    if isinstance(vision, Axis) and (joint is None or vision.joint_type is joint) \
            and vision.confidence >= min_confidence and (not door or moved >= config.vision_min_travel_deg):
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
