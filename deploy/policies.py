"""The opening policies (`--policy`, `[opening] policy`): strategy objects chosen by name from a registry, like
every camera, arm, segmenter and estimator. Each says what it acts with and how it steps:

- closed: re-estimates the axis after every step, with the run's estimator and cue fusion; a door's pulls follow
  arcs about its hinge, steps of `[opening] drawer_step_m` / `door_step_deg`;
- open: the same, but estimates once, after the first pull, and keeps that axis to the end;
- paper: the paper's schedule: its box estimator (`paper-obb`) on vision alone, straight steps growing from 10 to
  16 cm along a drawer and from 7 to 15 cm along a door's tangent (its first pull straight too).

No code outside this registry tests a policy's name: the episode asks its policy object.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from deploy.errors import ConfigError
from deploy.geometry.types import JointType
from drivers.registry import Registry

if TYPE_CHECKING:
    from deploy.config import OpeningConfig

Fusion = Literal["vision", "trajectory", "fused", "force"]


@dataclass(frozen=True)
class ConfiguredSteps:
    """Steps of the run's `[opening] drawer_step_m` (m along a drawer) and `door_step_deg` (about a door's hinge)."""

    def size(self, joint: JointType, k: int, opening: OpeningConfig) -> float:
        """Step k's size: metres (prismatic) or radians (revolute)."""
        return opening.drawer_step_m if joint is JointType.PRISMATIC else float(np.radians(opening.door_step_deg))


@dataclass(frozen=True)
class GrowingSteps:
    """Straight pulls that grow by `grow_m` each step from the first to the last size of `drawer_m` or `door_m`
    (metres along a drawer's line or a door's tangent, for both joints)."""

    drawer_m: tuple[float, float]
    door_m: tuple[float, float]
    grow_m: float

    def size(self, joint: JointType, k: int, opening: OpeningConfig) -> float:
        """Step k's size in metres of straight pull (0-based k)."""
        start, end = self.drawer_m if joint is JointType.PRISMATIC else self.door_m
        return min(start + self.grow_m * k, end)


@dataclass(frozen=True)
class OpeningPolicy:
    """What an opening acts with and how it steps.

    estimator: the axis estimator it acts with (None: the run's `[estimator] name`); fusion: how it weighs vision
    against the gripper's path and the force cue (None: the run's `[opening] fusion`); re_estimates: after every
    step (closed loop), else once after the first pull; door_arcs: a door's first pull, planned pulls and steps
    follow arcs about its likely or estimated hinge, else straight lines (the arc's tangent); steps: the step sizes.
    """

    name: str
    estimator: str | None
    fusion: Fusion | None
    re_estimates: bool
    door_arcs: bool
    steps: ConfiguredSteps | GrowingSteps

    def acting_estimator(self, configured: str) -> str:
        """The estimator the episode acts with, given the run's `configured` one."""
        return self.estimator or configured

    def acting_fusion(self, configured: Fusion) -> Fusion:
        """The fusion the episode acts with, given the run's `configured` one."""
        return self.fusion or configured

    def step_size(self, joint: JointType, k: int, opening: OpeningConfig) -> float:
        """Step k (0-based): metres, or radians about a door's hinge where the policy follows arcs."""
        return self.steps.size(joint, k, opening)

    def straight_door(self, joint: JointType) -> bool:
        """Whether a pull on `joint` goes straight where a door's would follow an arc."""
        return joint is JointType.REVOLUTE and not self.door_arcs


POLICIES: Registry[OpeningPolicy] = Registry("policy", ConfigError)  # factories: factory(argument)
POLICIES.register("closed", "deploy.policies:closed", "re-estimate the axis after every step")
POLICIES.register("open", "deploy.policies:open_loop", "estimate once, after the first pull, and keep that axis")
POLICIES.register("paper", "deploy.policies:paper", "the paper's straight steps and box estimator (paper-obb), "
                  "on vision alone")


def opening_policy(name: str) -> OpeningPolicy:
    """The policy registered as `name`; ConfigError naming the choices for an unknown one."""
    return POLICIES.open(name)


def closed(_argument: str = "") -> OpeningPolicy:
    return OpeningPolicy("closed", None, None, re_estimates=True, door_arcs=True, steps=ConfiguredSteps())


def open_loop(_argument: str = "") -> OpeningPolicy:
    return OpeningPolicy("open", None, None, re_estimates=False, door_arcs=True, steps=ConfiguredSteps())


def paper(_argument: str = "") -> OpeningPolicy:
    """The paper's schedule (its gripper-path and force cues are this project's, not the paper's: vision alone)."""
    return OpeningPolicy("paper", "paper-obb", "vision", re_estimates=True, door_arcs=False,
                         steps=GrowingSteps(drawer_m=(0.10, 0.16), door_m=(0.07, 0.15), grow_m=0.02))
