"""Options and choices that several `deploy` command groups share, defined once.

An option whose meaning differs per group (what `--camera` accepts, what `--yes` skips) comes from a function
here that takes the group's help, so its flag and type are the same in every group.
"""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from deploy.geometry.estimators.registry import ESTIMATORS
from deploy.perception.registry import SEGMENTERS
from drivers.arm.registry import ARMS
from drivers.camera.registry import CAMERAS
from drivers.registry import Registry


class JointChoice(str, Enum):
    auto = "auto"
    prismatic = "prismatic"
    revolute = "revolute"


class Task(str, Enum):
    drawer = "drawer"
    door = "door"


class Split(str, Enum):
    train = "train"
    test = "test"


class PolicyChoice(str, Enum):
    closed = "closed"
    open = "open"
    paper = "paper"


def yes_option(help: str) -> Any:
    """`--yes/-y`: skip the confirmation `help` names."""
    return Annotated[bool, typer.Option("--yes", "-y", help=help)]


def dry_run_option(help: str) -> Any:
    """`--dry-run`: do what `help` says and move nothing."""
    return Annotated[bool, typer.Option("--dry-run", help=help)]


def kind_option(registry: Registry, flag: str, note: str = "", optional: bool = False) -> Any:
    """`--camera`, `--arm`, `--segmenter`, `--estimator`: help and shell completion from the kind's registry
    (an unknown name is the registry's one-line error); `note` adds what this group does with it."""
    return Annotated[str | None if optional else str, typer.Option(
        flag, help=f"{registry.help()}.{note}", autocompletion=lambda: registry.names())]


def robot_option(help: str) -> Any:
    """`--robot PATH` of a robot config TOML."""
    return Annotated[Path | None, typer.Option("--robot", help=help)]


def seed_option(help: str) -> Any:
    """`--seed N`; `help` says what it seeds."""
    return Annotated[int, typer.Option("--seed", help=help)]


CameraOpt = kind_option(CAMERAS, "--camera")
ArmOpt = kind_option(ARMS, "--arm")
SegmenterOpt = kind_option(SEGMENTERS, "--segmenter", " \\[default: oracle in simulation, gdino-sam2 otherwise]",
                           optional=True)
EstimatorOpt = kind_option(ESTIMATORS, "--estimator", " \\[default: the config's, screw-grip]", optional=True)
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")]
PolicyOpt = Annotated[PolicyChoice, typer.Option(help="closed (re-estimate every step), open or paper.")]
RobotOpt = robot_option("Robot config TOML \\[default: configs/robots/panda_sim.toml].")
StationSeedOpt = seed_option("Seed of the station generator (and sim noise).")
