"""`deploy open-drawer|open-door|open`: one opening episode, simulated or on the real arm and camera."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    ArmOpt,
    CameraOpt,
    JointChoice,
    JsonOpt,
    PolicyChoice,
    PolicyOpt,
    SegmenterOpt,
    Split,
    Task,
    dry_run_option,
    robot_option,
    seed_option,
    yes_option,
)
from deploy.commands.output import print_json, print_rows

top_level = typer.Typer()  # its commands sit directly under `deploy`

SeedOpt = seed_option("Simulated scenario seed (--camera sim).")
RobotOpt = robot_option("Robot config TOML for --arm can (see docs/arm.md).")
CalibrationOpt = Annotated[Path | None, typer.Option(
    help="Hand-eye calibration file \\[default: the one saved for this camera and robot].")]
RunDirOpt = Annotated[Path | None, typer.Option(help="Run folder \\[default: runs/TASK-TIME].")]
SplitOpt = Annotated[Split, typer.Option(help="Object family (--camera sim).")]
DryRunOpt = dry_run_option("Perceive and plan the grasp; move nothing.")
YesOpt = yes_option("Skip the confirmation before a real arm's first motion.")
ViewOpt = Annotated[bool, typer.Option("--view", help="Stream frames, clouds and axes to a rerun viewer.")]


def _print_episode(data: dict, json_out: bool) -> None:
    if json_out:
        print_json(data)
        return
    where = f"seed {data['seed']}" if "seed" in data else data.get("camera", "")
    keys = ("success", "opened", "target", "true_opened", "steps", "stop_reason", "message", "axis_angle_error_deg",
            "axis_position_error_m", "run_dir")
    print_rows(f"{data['task']} episode ({where}, {data['policy']} loop)", {k: data[k] for k in keys if k in data})


def _open(request_fields: dict, json_out: bool) -> None:
    from deploy.control.session import OpenRequest, open_object

    data = open_object(OpenRequest(**request_fields))
    _print_episode(data, json_out)
    if not (data["success"] or data["stop_reason"] == "dry run"):
        raise typer.Exit(1)


@top_level.command("open-drawer")
def open_drawer(
    distance: Annotated[float, typer.Option(help="Target opening (m).")] = 0.30,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOpt = PolicyChoice.closed,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open a drawer to the target, re-estimating its axis after every step.

    Example: deploy open-drawer --distance 0.30 --seed 3 --json
    Example: deploy open-drawer --camera d415 --arm can --robot configs/robots/damiao_6dof.toml --dry-run
    """
    _open(dict(task="drawer", scene="drawer", distance_m=distance, camera=camera, arm=arm, robot=robot,
               calibration=calibration, segmenter=segmenter, seed=seed, split=split.value, policy=policy.value,
               run_dir=run_dir, dry_run=dry_run, yes=yes, view=view), json_out)


@top_level.command("open-door")
def open_door(
    angle: Annotated[float, typer.Option(help="Target opening (deg).")] = 45.0,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOpt = PolicyChoice.closed,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open a door to the target angle along arcs about its estimated hinge axis.

    Example: deploy open-door --angle 45 --seed 2 --json
    """
    _open(dict(task="door", scene="door", angle_deg=angle, camera=camera, arm=arm, robot=robot,
               calibration=calibration, segmenter=segmenter, seed=seed, split=split.value, policy=policy.value,
               run_dir=run_dir, dry_run=dry_run, yes=yes, view=view), json_out)


@top_level.command("open")
def open_any(
    joint: Annotated[JointChoice, typer.Option(
        help="auto: drawer or door from a 2.5 cm probe pull (how the front turns); or say which.")] = JointChoice.auto,
    distance: Annotated[float, typer.Option(help="Target if it is a drawer (m).")] = 0.30,
    angle: Annotated[float, typer.Option(help="Target if it is a door (deg).")] = 45.0,
    scene: Annotated[Task, typer.Option(help="Simulated object (--camera sim).")] = Task.drawer,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOpt = PolicyChoice.closed,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open whatever is in front of the arm: a drawer to --distance or a door to --angle.

    Example: deploy open --joint auto --scene door --seed 4 --json
    """
    task = {"auto": "auto", "prismatic": "drawer", "revolute": "door"}[joint.value]
    _open(dict(task=task, scene=scene.value, distance_m=distance, angle_deg=angle, camera=camera, arm=arm,
               robot=robot, calibration=calibration, segmenter=segmenter, seed=seed, split=split.value,
               policy=policy.value, run_dir=run_dir, dry_run=dry_run, yes=yes, view=view), json_out)
