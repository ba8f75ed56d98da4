"""`deploy open-drawer|open-door|open`: one opening episode, simulated or on the real arm and camera."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    WORLD_HELP,
    ArmOpt,
    AssetsOpt,
    BitrateOpt,
    BoxOpt,
    CalibrationErrorOpt,
    CameraOpt,
    ChannelOpt,
    ConfigFileOpt,
    DataBitrateOpt,
    FilterChoice,
    FilterOpt,
    InterfaceOpt,
    JointChoice,
    JsonOpt,
    ObjectOpt,
    PartOpt,
    PointOpt,
    PolicyChoice,
    PromptOpt,
    ScaleChoice,
    ScaleOpt,
    SegmenterOpt,
    SimFaultOpt,
    Split,
    Task,
    WorldChoice,
    can_settings,
    dry_run_option,
    overwrite_option,
    robot_option,
    seed_option,
    yes_option,
)
from deploy.commands.output import print_json, print_rows
from deploy.config import CALIBRATION_ERROR
from deploy.policies import POLICIES

top_level = typer.Typer()  # its commands sit directly under `deploy`

SeedOpt = seed_option("Simulated scenario seed (--camera sim).")
RobotOpt = robot_option("Robot config for --arm can: a TOML file, or a shipped one's name (damiao_6dof is the "
                        "template; docs/arm.md).")
CalibrationOpt = Annotated[Path | None, typer.Option(
    help="Hand-eye calibration file \\[default: the one saved for this camera and robot].")]
RunDirOpt = Annotated[Path | None, typer.Option(help="Run folder \\[default: runs/TASK-TIME].")]
SplitOpt = Annotated[Split, typer.Option(help="Object family (--camera sim).")]
DryRunOpt = dry_run_option("Perceive and plan the grasp; move nothing.")
YesOpt = yes_option("Skip the confirmation before a real arm's first motion.")
ViewOpt = Annotated[bool, typer.Option("--view", help="Show frames, the camera, clouds and axes (estimated per step; "
                                      "true in simulation) in a rerun viewer, saved to RUN/episode.rrd.")]
OverwriteOpt = overwrite_option("run folder at --run-dir")
PolicyOrConfigOpt = Annotated[PolicyChoice | None, typer.Option(
    help=f"{POLICIES.help()} \\[default: the config's, closed].")]
DistanceOpt = Annotated[float | None, typer.Option(
    "--distance", help="Target opening of a drawer, in metres \\[default: the config's, 0.30].")]
AngleOpt = Annotated[float | None, typer.Option(
    "--angle", help="Target opening of a door, in degrees \\[default: the config's, 45].")]


class Condition(str, Enum):
    normal = "normal"
    locked = "locked"
    stiff = "stiff"


OpenWorldOpt = Annotated[WorldChoice | None, typer.Option(
    "--world", help=f"The simulated world (--camera sim): {WORLD_HELP} \\[default: kitchen].")]
ConditionOpt = Annotated[Condition, typer.Option(
    help="The simulated object's joint (--camera sim; the controller is not told): normal, locked (held fast) or "
    "stiff (three times the friction).")]


def _overrides(filter_profile: FilterChoice | None, prompt: str | None,
               box: tuple[float, float, float, float] | None) -> dict:
    """--filter, --prompt and --box as settings by dotted name (None: the config's)."""
    return {"filter.profile": filter_profile.value if filter_profile is not None else None,
            "perception.object_prompt": prompt, "perception.box": box}


def _request_fields(o: dict) -> dict:
    """The OpenRequest fields every open command shares, from the command's options `o` (its `locals()`)."""
    return dict(camera=o["camera"], arm=o["arm"], robot=o["robot"],
                can=can_settings(o["interface"], o["channel"], o["bitrate"], o["data_bitrate"]),
                calibration=o["calibration"], segmenter=o["segmenter"], seed=o["seed"], split=o["split"].value,
                policy=_value(o["policy"]), run_dir=o["run_dir"], dry_run=o["dry_run"], yes=o["yes"], view=o["view"],
                calibration_error=o["calibration_error"], condition=o["condition"].value, config_file=o["config"],
                overrides=_overrides(o["filter_profile"], o["prompt"], o["box"]),
                **_scene(o["world"], o["part"], o["assets"], o["object_id"], o["scale"], o["point"]))


def _scene(world: WorldChoice | None, part: str | None, assets: Path | None, object_id: str | None,
           scale: ScaleChoice, point: tuple[float, float] | None) -> dict:
    """The simulated scene's options and --point as OpenRequest fields (world None: not given)."""
    return {"world": world.value if world is not None else None, "part": part, "assets": assets,
            "object_id": object_id, "scale": scale.value, "point": point}


def _print_episode(data: dict, json_out: bool) -> None:
    if json_out:
        print_json(data)
        return
    where = f"seed {data['seed']}" if "seed" in data else data.get("camera", "")
    keys = ("success", "world", "furniture", "object", "part", "pointer", "opened_m", "opened_deg", "target_m",
            "target_deg", "true_opened_m", "true_opened_deg",
            "steps", "stop_reason", "message", "peak_pull_force_n", "axis_angle_error_deg", "axis_position_error_m",
            "run_dir")
    rows = {k: data[k] for k in keys if k in data}
    used = data["filter"]
    rows["filter"] = f"{used['profile']}: radius {used['radius_m']:g} m, eps {used['eps']}"
    if "rrd" in data:  # --view
        shown = "shown live" if data["rrd"]["live"] else "no viewer opened (no display): open it with rerun FILE"
        rows["rrd"] = f"{data['rrd']['path']} ({shown})"
    print_rows(f"{data['task']} episode ({where}, {data['policy']} loop)", rows)


def _value(choice: PolicyChoice | None) -> str | None:
    return None if choice is None else choice.value


def _open(request_fields: dict, json_out: bool, sim_fault: list[str] | None, overwrite: bool) -> None:
    """Check the request (--calibration only with a real camera, --condition only with a simulated one,
    --sim-fault only with sim-can, the run config and the device names, the run folder new or --overwrite and
    apart from a replayed recording), then run it; a run refused before it wrote anything leaves no folder."""
    from dataclasses import replace

    from deploy.arm_bringup import inject_sim_faults, parse_sim_faults
    from deploy.control.session import OpenRequest, check_request, open_object
    from deploy.control.state import StopReason
    from deploy.errors import ConfigError
    from deploy.output_folder import new_output, replay_input
    from deploy.perception.registry import SEGMENTERS
    from drivers.arm.registry import ARMS
    from drivers.camera.registry import CAMERAS

    faults = parse_sim_faults(request_fields["arm"], sim_fault)
    simulated = CAMERAS.entry(request_fields["camera"])[0].simulated
    _check_scene_options(request_fields, simulated)
    request = OpenRequest(**{**request_fields, "world": request_fields["world"] or "kitchen"})
    if request.calibration is not None and simulated:
        raise ConfigError(f"--calibration {request.calibration} is for a real camera: the simulated camera's pose "
                          "comes from the simulation; drop --calibration, or use --camera d415")
    if simulated:
        from sim_fallback.scenes import check_scene

        check_scene(request.world, request.assets, request.object_id)
    request.config()  # a value the run config refuses (--distance, --angle, --config) fails here, before any folder
    check_request(request)
    ARMS.entry(request.arm)
    if request.segmenter is not None:
        SEGMENTERS.entry(request.segmenter)
    with new_output(request.folder() if request.run_dir is None else request.run_dir, overwrite, "run folder",
                    "--run-dir", replay_input(request.camera), claimed=request.run_dir is None) as run_dir:
        data = open_object(replace(request, run_dir=run_dir),
                           confirm=lambda question: typer.confirm(question, abort=True),
                           setup=(lambda _world, arm: inject_sim_faults(arm, faults)) if faults else None)
    _print_episode(data, json_out)
    if not (data["success"] or data["stop_reason"] == StopReason.DRY_RUN):
        raise typer.Exit(1)


def _check_scene_options(fields: dict, simulated: bool) -> None:
    """ConfigError for an option of the simulated scene given with a real camera or a recording."""
    from deploy.errors import ConfigError

    given = {"--world": fields["world"], "--part": fields["part"], "--assets": fields["assets"],
             "--object": fields["object_id"], "--scale": None if fields["scale"] == "real" else fields["scale"],
             "--condition": None if fields["condition"] == "normal" else fields["condition"]}
    for option, value in given.items():
        if value is not None and not simulated:
            raise ConfigError(f"{option} {value} is for a simulated scene: drop it, or use --camera sim")


@top_level.command("open-drawer")
def open_drawer(
    distance: DistanceOpt = None,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOrConfigOpt = None,
    config: ConfigFileOpt = None,
    filter_profile: FilterOpt = None,
    prompt: PromptOpt = None,
    box: BoxOpt = None,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    calibration_error: CalibrationErrorOpt = CALIBRATION_ERROR,
    condition: ConditionOpt = Condition.normal,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    world: OpenWorldOpt = None,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    point: PointOpt = None,
    sim_fault: SimFaultOpt = None,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open a drawer to the target, re-estimating its axis after every step.

    Example: deploy open-drawer --distance 0.30 --seed 3 --json
    Example: deploy open-drawer --camera d415 --arm can --robot my_arm.toml --dry-run
    Example: deploy open-drawer --camera d415 --arm can --robot my_arm.toml --config run.toml --prompt drawer
    """
    _open(dict(task="drawer", scene="drawer", distance_m=distance, **_request_fields(locals())), json_out, sim_fault,
          overwrite)


@top_level.command("open-door")
def open_door(
    angle: AngleOpt = None,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOrConfigOpt = None,
    config: ConfigFileOpt = None,
    filter_profile: FilterOpt = None,
    prompt: PromptOpt = None,
    box: BoxOpt = None,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    calibration_error: CalibrationErrorOpt = CALIBRATION_ERROR,
    condition: ConditionOpt = Condition.normal,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    world: OpenWorldOpt = None,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    point: PointOpt = None,
    sim_fault: SimFaultOpt = None,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open a door to the target angle along arcs about its estimated hinge axis.

    Example: deploy open-door --angle 45 --seed 2 --json
    """
    _open(dict(task="door", scene="door", angle_deg=angle, **_request_fields(locals())), json_out, sim_fault, overwrite)


@top_level.command("open")
def open_any(
    joint: Annotated[JointChoice, typer.Option(
        help="auto: drawer or door from a 2.5 cm probe pull (how the front turns); or say which.")] = JointChoice.auto,
    distance: DistanceOpt = None,
    angle: AngleOpt = None,
    task: Annotated[Task, typer.Option(help="Simulated object (--camera sim).")] = Task.drawer,
    scene: Annotated[Task | None, typer.Option(hidden=True, help="Old name of --task.")] = None,
    camera: CameraOpt = "sim",
    arm: ArmOpt = "sim",
    robot: RobotOpt = None,
    calibration: CalibrationOpt = None,
    segmenter: SegmenterOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    policy: PolicyOrConfigOpt = None,
    config: ConfigFileOpt = None,
    filter_profile: FilterOpt = None,
    prompt: PromptOpt = None,
    box: BoxOpt = None,
    run_dir: RunDirOpt = None,
    dry_run: DryRunOpt = False,
    yes: YesOpt = False,
    view: ViewOpt = False,
    calibration_error: CalibrationErrorOpt = CALIBRATION_ERROR,
    condition: ConditionOpt = Condition.normal,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    world: OpenWorldOpt = None,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    point: PointOpt = None,
    sim_fault: SimFaultOpt = None,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Open whatever is in front of the arm: a drawer to --distance or a door to --angle.

    Example: deploy open --joint auto --task door --seed 4 --json
    """
    told = {"auto": "auto", "prismatic": "drawer", "revolute": "door"}[joint.value]
    _open(dict(task=told, scene=(scene or task).value, distance_m=distance, angle_deg=angle,
               **_request_fields(locals())), json_out, sim_fault, overwrite)
