"""What an opening episode knows and how it ended: one state record in SI units (m, rad), stop reasons as an
enum, and the exception a stage raises to end the episode."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from deploy.control.grasp import Handle
from deploy.geometry.types import Axis, JointType
from drivers.camera.base import Frame


class StopReason(str, Enum):
    """Why an episode ended (the `stop_reason` of its JSON)."""

    TARGET_REACHED = "target reached"
    DRY_RUN = "dry run"
    BLOCKED = "blocked"
    GRASP_LOST = "grasp lost"
    GRASP_FAILED = "grasp failed"
    TRACKING_LOST = "tracking lost"
    IK_INFEASIBLE = "ik infeasible"
    ARM_ERROR = "arm error"
    TIMEOUT = "timeout"
    MAX_STEPS = "max steps"
    NO_HANDLE = "no handle"
    NO_OBJECT = "no object"
    POINTER_REFUSED = "pointer refused"
    NO_CLEAR_PATH = "no clear path"
    NOT_FOLLOWED = "part did not follow"
    INTERRUPTED = "interrupted"


class EpisodeStop(Exception):
    """Raised by a stage to end the episode with `reason` and a message saying what happened and what to do."""

    def __init__(self, reason: StopReason, message: str) -> None:
        super().__init__(message)
        self.reason, self.message = reason, message


@dataclass
class EpisodeState:
    """Everything the episode has learnt so far. Openings are m (prismatic) or rad (revolute) along or about
    `axis`; `opened` = `opened_before` (up to the last grasp) + the grip point's travel since `p_grasp`."""

    t0: float
    joint: JointType | None = None  # told by the task, or classified by the probe pull
    handle: Handle | None = None
    axis: Axis | None = None  # the axis acted on
    estimated: bool = False  # an estimate (not a prior) has been acted on
    opened: float = 0.0
    opened_before: float = 0.0
    p_grasp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    open_width_m: float = 0.0
    steps: int = 0
    regrasped: bool = False
    reseats: int = 0  # a drawer's handle taken again from another arm configuration (its pull out of reach)
    turned_regrasps: int = 0  # a door's handle held again with the hand turned back toward the robot
    prior_blocks: int = 0  # a door's steps blocked across their arc about the hinge prior that went on
    turn_hinge: Axis | None = None  # the door's hinge its front's turn placed last (`stages._hinge_seen_turning`)
    followed: bool = False  # the camera saw the pointed drawer leave its place (`stages._check_followed`)
    peak_pull_force_n: float = 0.0  # the largest force the tool applied while pulling (N, joint torques)
    across_force_n: float = 0.0  # the last pull's largest force across its path (N): its axis was off
    vision_axis: Axis | None = None  # vision's latest estimate, oriented (what vision alone would act on)
    estimates: list[dict] = field(default_factory=list)
    commanded: list[np.ndarray] = field(default_factory=list)
    measured: list[np.ndarray] = field(default_factory=list)
    grip_start: int = 0  # where in `measured` the current grip's poses begin (a re-grasp after a slip holds the
    # handle at another point of it)
    opening_curve: list[tuple[float, float]] = field(default_factory=list)  # (arm time s, opening SI)
    timings: dict[str, float] = field(default_factory=lambda: {
        "perceive_s": 0.0, "grasp_s": 0.0, "motion_s": 0.0, "estimate_s": 0.0})

    def joint_type(self) -> JointType:
        """The joint acted on: told or classified, else the axis's, else prismatic."""
        return self.joint or (self.axis.joint_type if self.axis is not None else JointType.PRISMATIC)


def display_scale(joint_type: JointType | str | None) -> float:
    """Factor from SI to the units shown to users: degrees for a revolute joint, metres otherwise."""
    return float(np.degrees(1.0)) if JointType(joint_type or "prismatic") is JointType.REVOLUTE else 1.0


def opening_unit(joint_type: JointType | str | None) -> str:
    """The unit openings are shown in: "deg" for a revolute joint, "m" otherwise."""
    return "deg" if JointType(joint_type or "prismatic") is JointType.REVOLUTE else "m"


@dataclass
class EpisodeResult:
    """How an episode ended. `opened` / `target` in SI units (m or rad, by `joint_type`); the JSON shows
    metres or degrees. `first_frame` is kept for the report."""

    success: bool
    opened: float
    target: float
    steps: int
    joint_type: str | None
    axis: Axis | None
    stop_reason: StopReason
    message: str
    run_dir: Path | None
    timings: dict[str, float]
    regrasped: bool = False
    peak_pull_force_n: float = 0.0
    vision_axis: Axis | None = None
    estimates: list[dict] = field(default_factory=list)
    commanded: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    measured: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    opening_curve: list[tuple[float, float]] = field(default_factory=list)
    first_frame: Frame | None = None

    @property
    def scale(self) -> float:
        return display_scale(self.joint_type)

    @property
    def unit(self) -> str:
        return opening_unit(self.joint_type)

    def to_dict(self) -> dict:
        """The JSON result of `deploy open --json`: openings under keys naming their unit (opened_m / opened_deg)."""
        def axis_dict(axis: Axis | None) -> dict | None:
            return None if axis is None else {
                k: v for k, v in axis.to_dict().items() if k in ("joint_type", "origin", "direction")}

        axis = axis_dict(self.axis)
        return {"success": self.success, f"opened_{self.unit}": self.opened * self.scale,
                f"target_{self.unit}": self.target * self.scale, "steps": self.steps, "axis": axis,
                "stop_reason": self.stop_reason.value, "message": self.message,
                "regrasped": self.regrasped, "peak_pull_force_n": self.peak_pull_force_n,
                "vision_axis": axis_dict(self.vision_axis),
                "run_dir": None if self.run_dir is None else str(self.run_dir),
                "timings": self.timings}
