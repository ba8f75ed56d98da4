"""`deploy bench ...`: accuracy and speed of every area, the numbers in docs/benchmarks.md."""

from __future__ import annotations

from enum import Enum
from typing import Annotated

import typer

from deploy.commands.open import Condition
from deploy.commands.options import (
    AssetsOpt,
    CalibrationErrorOpt,
    JsonOpt,
    ObjectOpt,
    PartOpt,
    PolicyChoice,
    PolicyOpt,
    RobotOpt,
    ScaleChoice,
    ScaleOpt,
    Split,
    StationSeedOpt,
    Task,
    WorldChoice,
    WorldOpt,
    above,
)
from deploy.commands.output import console, err_console, fmt, print_json, print_rows, print_table, progress_bar
from deploy.config import CALIBRATION_ERROR, OpeningConfig
from deploy.perception.registry import SEGMENTERS

OPENING = OpeningConfig()  # the defaults of the opening targets and policy
DEFAULT_POLICY = PolicyChoice(OPENING.policy)
MAX_EPISODES, MAX_WORKERS, MAX_SEQUENCES = 100_000, 64, 100  # every job is built up front; a sequence is ~60 MB
SEQUENCES = 20  # bench axis's default sequences per object kind
MAX_ARM_SECONDS = 3600.0
OPENABLE = [e for e in SEGMENTERS.entries() if "box" not in e.needs]  # bench open gives no first box per scene
app = typer.Typer(help="Benchmarks: accuracy and speed, results for docs/benchmarks.md.", no_args_is_help=True)
BenchSegmenterOpt = Annotated[str | None, typer.Option(
    "--segmenter", autocompletion=lambda: [e.name for e in OPENABLE],
    help="; ".join(f"{e.usage}: {e.description}" for e in OPENABLE)
    + " \\[default: gdino-sam2 where its weights are on this machine, else rgbd]. Not "
    + " or ".join(e.name for e in SEGMENTERS.entries() if e not in OPENABLE)
    + ", which needs the object's box on each scene's first frame.")]
BenchConditionOpt = Annotated[Condition, typer.Option(
    help="Every simulated object's joint (the controller is not told): normal, locked (held fast) or stiff (three "
    "times the friction).")]


class JointTold(str, Enum):
    auto = "auto"


class Scenes(str, Enum):
    standard = "standard"
    varied = "varied"
    paths = "paths"


@app.command("axis")
def bench_axis_cmd(
    sequences: Annotated[int | None, typer.Option(
        min=1, max=MAX_SEQUENCES, help="Sequences per object kind (RGB-D scene sets; about 60 MB each, all held at "
        f"once); not with --scenes paths, a fixed set \\[default: {SEQUENCES}].")] = None,
    seed: Annotated[int, typer.Option(min=0, help="Random seed.")] = 0,
    scenes: Annotated[Scenes, typer.Option(
        help="standard: 10 cm / 20 deg openings seen from above and aside; varied: short, eased openings seen "
        "head-on to 60 deg aside, below to above; paths: 60 hand-recorded-like handle trajectories for "
        "fit-trajectory.")] = Scenes.standard,
    json_out: JsonOpt = False,
) -> None:
    """Axis accuracy (median, p90, max) and speed of every estimator on synthetic data with known axes.

    Example: deploy bench axis --sequences 50 --json
    Example: deploy bench axis --scenes varied --seed 1
    Example: deploy bench axis --scenes paths --json
    """
    if scenes is Scenes.paths:
        if sequences is not None:
            from deploy.errors import ConfigError

            raise ConfigError(f"--sequences {sequences} with --scenes paths: the paths set is fixed (60 handle "
                              "trajectories drawn with --seed); leave out --sequences, or use --scenes standard or "
                              "varied")
        _bench_axis_paths(seed, json_out)
        return
    from deploy.bench.axis import bench_axis

    with progress_bar("bench axis") as bar:
        data = bench_axis(sequences or SEQUENCES, seed, progress=bar.counts, scenes=scenes.value)
    if json_out:
        print_json(data)
        return

    def spread(s: dict, key: str, scale: float = 1.0) -> str:
        return " / ".join(fmt(s[f"{key}_{q}"], scale) for q in ("median", "p90", "max"))

    print_table(
        f"axis estimators on {data['sequences']} synthetic sequences ({scenes.value} scenes, seed {seed})",
        ("estimator", "drawer deg med/p90/max", "door deg med/p90/max", "door pos cm med/p90/max", "joint acc",
         "failed", "2 sigma cover", "ms med"),
        [(name, spread(s, "drawer_angle_deg"), spread(s, "door_angle_deg"), spread(s, "door_position_m", 100),
          f"{s['joint_type_accuracy']:.2f}", str(s["failed_estimates"]), _coverage(s), fmt(s["ms_median"], digits=1))
         for name, s in data["estimators"].items()],
    )
    console.print("2 sigma cover: the share of the estimates reporting a direction sigma whose angle error is within "
                  "2 sigma (of how many); 90-99 % is a well-calibrated sigma")
    console.print(f"full geometry step ({data['step_estimator']}), median: {fmt(data['step_ms_median'], digits=1)} ms")
    for name, s in data["estimators"].items():
        for reason, count in s["failures"].items():
            console.print(f"{name} failed {count}x: {reason}")


def _coverage(summary: dict) -> str:
    share = summary["coverage_2_sigma"]
    return "-" if share is None else f"{share * 100:.0f} % of {summary['coverage_estimates']}"


def _bench_axis_paths(seed: int, json_out: bool) -> None:
    """`bench axis --scenes paths`: fit-trajectory on the handle-trajectory set."""
    from deploy.bench.axis_paths import bench_axis_paths

    with progress_bar("bench axis paths") as bar:
        data = bench_axis_paths(seed, progress=bar.counts)
    if json_out:
        print_json(data)
        return
    rows = []
    for kind, k in data["kinds"].items():
        auto, given = k["angle_deg"], k["given_angle_deg"]
        rows.append((kind, f"{k['right']}/{k['paths']}", " / ".join(fmt(auto[q]) for q in ("median", "p90", "max")),
                     " / ".join(fmt(given[q]) for q in ("median", "p90", "max"))))
    print_table(f"fit-trajectory on {data['paths']} handle trajectories (seed {seed}): joint type "
                f"{data['joint_type_accuracy']:.2f}, {data['wrong_type']} wrong, {data['undecided']} undecided",
                ("kind", "type right", "deg med/p90/max (auto)", "deg med/p90/max (type given)"), rows)
    console.print("object medians (deg): " + ", ".join(
        f"{name} {fmt(value)}" for name, value in data["object_median_angle_deg"].items()))
    for cause, count in data["undecided_causes"].items():
        console.print(f"undecided {count}x: {cause}")


@app.command("open")
def bench_open_cmd(
    task: Annotated[Task, typer.Option(help="drawer or door.")] = Task.drawer,
    distance: Annotated[float | None, typer.Option(callback=above(0.0), help="Target opening of a drawer, in "
                                                   f"metres \\[default: {OPENING.target_distance_m:g}].")] = None,
    angle: Annotated[float | None, typer.Option(callback=above(0.0), help="Target opening of a door, in degrees "
                                                f"\\[default: {OPENING.target_angle_deg:g}].")] = None,
    target: Annotated[float | None, typer.Option(callback=above(0.0), hidden=True,
                                                 help="Old name: the target in m (drawer) or deg (door).")] = None,
    episodes: Annotated[int, typer.Option(min=1, max=MAX_EPISODES, help="Episodes (consecutive scenario seeds).")
                        ] = 10,
    split: Annotated[Split, typer.Option(help="Object family.")] = Split.test,
    policy: PolicyOpt = DEFAULT_POLICY,
    seed: Annotated[int, typer.Option(min=0, help="First scenario seed.")] = 0,
    workers: Annotated[int, typer.Option(min=1, max=MAX_WORKERS, help="Local worker processes (about 0.5 GB "
                                         "each); more than this machine's cores is warned about (the timings then "
                                         "include waiting for a core).")] = 1,
    ray: Annotated[str | None, typer.Option(
        "--ray", metavar="ADDRESS", help="Run episodes on a Ray cluster: local, auto, ray://HOST:10001 or "
        "HOST:6379 (needs the cluster extra); --workers is then unused.")] = None,
    joint: Annotated[JointTold | None, typer.Option(
        help="auto: the policy is not told the joint and classifies it from its probe pull \\[default: told "
        "the task's].")] = None,
    auto_joint: Annotated[bool, typer.Option("--auto-joint", hidden=True, help="Old name of --joint auto.")] = False,
    segmenter: BenchSegmenterOpt = None,
    calibration_error: CalibrationErrorOpt = CALIBRATION_ERROR,
    condition: BenchConditionOpt = Condition.normal,
    robot: RobotOpt = None,
    world: WorldOpt = WorldChoice.kitchen,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    json_out: JsonOpt = False,
) -> None:
    """Success rate of simulated openings (success = the true joint value exceeds the target, like the paper),
    with what a real robot senses: the default segmenter, a calibrated (imperfect) camera pose, and of the part only
    the pixel a user would point at on it; per part, and with --assets per object.

    Example: deploy bench open --task door --angle 45 --episodes 20 --workers 2 --json
    Example: deploy bench open --task drawer --assets partnet-mobility-dataset/ --episodes 20 --workers 2
    Example: deploy bench open --task drawer --distance 0.30 --episodes 1000 --ray ray://head:10001 --json
    Example: deploy bench open --task drawer --world box --condition locked --episodes 20 --workers 2 --json
    """
    from deploy.bench.open import bench_open

    goal = _bench_target(task, distance, angle, target, segmenter)
    unit = "m" if task is Task.drawer else "deg"
    with progress_bar(f"bench open {task.value}", episodes) as bar:
        data = bench_open(task.value, goal, episodes, split.value, policy.value, seed, workers,
                          progress=bar.advance, ray_address=ray, auto_joint=auto_joint or joint is JointTold.auto,
                          segmenter=segmenter, calibration_error=calibration_error, condition=condition.value,
                          world=world.value, part=part, assets=assets, object_id=object_id, scale=scale.value,
                          robot=robot)
    if json_out:
        print_json(data)
        return
    tables = ("per_part", "objects", "unusable_objects")
    print_rows(f"{task.value} to {goal:g} {unit} in the {world.value} world ({split.value}, {policy.value} loop)",
               {k: v for k, v in data.items() if k not in tables})
    _print_groups("per part", data["per_part"])
    if "objects" in data:
        _print_groups("per object", data["objects"])
        for object_id, why in data["unusable_objects"].items():
            console.print(f"object {object_id} not used: {why}", soft_wrap=True)


def _print_groups(title: str, groups: dict) -> None:
    """`bench open`'s success by part or by object: episodes, successes, failures by cause (and an object's parts)."""
    def parts(g: dict) -> str:
        return ", ".join(f"{name} {p['successes']}/{p['episodes']}" for name, p in g.get("parts", {}).items())

    print_table(title, ("", "success", "failures", *(("parts",) if title == "per object" else ())),
                [(name, f"{g['successes']}/{g['episodes']}",
                  ", ".join(f"{cause} {n}" for cause, n in g["failures"].items()) or "none",
                  *((parts(g),) if title == "per object" else ())) for name, g in groups.items()])


@app.command("sim")
def bench_sim_cmd(
    world: WorldOpt = WorldChoice.kitchen,
    episodes: Annotated[int, typer.Option(min=1, max=20, help="Drawer scenarios (medians are reported).")] = 1,
    json_out: JsonOpt = False,
) -> None:
    """Physics steps per second, a camera frame's cost by step and the real-time factor of an opening, on the drawer
    scenarios of --world (seeds 0..).

    The real-time factor is a 10 s scripted opening with 640x480 frames at 10 Hz, with the default depth model (the
    D415 artefact model), active stereo and exact depth.
    Example: deploy bench sim --world kitchen --json
    """
    from sim_fallback.bench import bench_sim

    with progress_bar("bench sim") as bar:
        data = bench_sim(episodes, world.value, progress=bar.describe)
    if json_out:
        print_json(data)
        return
    flat = {k: v for k, v in data.items() if not isinstance(v, dict)}
    for key in ("frame_ms", "frame_ms_stereo"):
        flat.update({f"{key} {step}": ms for step, ms in data[key].items()})
    print_rows("simulation speed", flat, digits=2)


@app.command("depth")
def bench_depth_cmd(json_out: JsonOpt = False) -> None:
    """Fill rate and error of the simulated D415's depth (artefact model and active stereo) on walls facing the
    camera at 0.5, 1 and 2 m (plain light grey, wood-textured, dark), for comparing with the D415's published
    figures (docs/simulation.md).

    Example: deploy bench depth --json
    """
    from sim_fallback.bench import bench_depth

    with progress_bar("bench depth") as bar:
        data = bench_depth(progress=bar.describe)
    if json_out:
        print_json(data)
        return
    rows = [[r["model"], r["surface"], fmt(r["distance_m"]), fmt(r["fill"]), fmt(r["fill_central"]),
             fmt(r["rms_error_pct"]), fmt(r["left_band_px"]), fmt(r["expected_band_px"])] for r in data["rows"]]
    print_table("simulated D415 depth on a wall", ["model", "surface", "distance m", "fill", "fill central 80 %",
                                                    "RMS error % (central)", "left band px", "f B / Z px"], rows)


@app.command("perception")
def bench_perception_cmd(
    seeds: Annotated[int, typer.Option(min=1, help="Scenario seeds (a drawer and a door recording each).")] = 1,
    fps: Annotated[float, typer.Option(callback=above(0.0), max=60.0,
                                       help="Frames per second of the simulated recordings.")] = 10.0,
    world: WorldOpt = WorldChoice.kitchen,
    json_out: JsonOpt = False,
) -> None:
    """Per-frame latency of each segmenter backend and its mask IoU against the simulator's oracle masks, on scripted
    recordings in --world (a recording whose scripted grasp fails is left out and named).

    rgbd sees the frames with the arm's pixels removed (the self-filter, as in an episode). gdino-sam2 /
    gdino-edgetam are measured only where their weights are in the local cache (else skipped, naming each missing
    model and its fetch command).
    Example: deploy bench perception --seeds 2 --json
    """
    from deploy.perception.bench import bench_perception

    with progress_bar("bench perception") as bar:
        data = bench_perception(seeds, fps, progress=bar.describe, world=world.value)
    if json_out:
        print_json(data)
        return
    rows = []
    for name, r in data["backends"].items():
        if "skipped" in r:
            rows.append((name, f"skipped: {r['skipped']}", "", "", "", "", "0"))
        else:
            rows.append((name, f"{r['latency_ms_median']:.1f}", f"{r['latency_ms_p90']:.1f}",
                         f"{r['start_ms_median']:.0f}", f"{r['iou_median']:.3f}", f"{r['iou_min']:.3f}",
                         str(r["frames"])))
    print_table(f"segmenters on {data['recordings']} simulated recordings in the {world.value} world "
                f"({data['device']})",
                ("backend", "track ms median", "track ms p90", "start ms", "IoU median", "IoU min", "frames"), rows)
    for why in data["skipped_recordings"]:
        console.print(f"recording left out: {why}", soft_wrap=True)


@app.command("arm")
def bench_arm_cmd(
    robot: RobotOpt = None,
    samples: Annotated[int, typer.Option(min=1, help="IK and Ruckig samples.")] = 500,
    seconds: Annotated[float, typer.Option(callback=above(0.0), max=MAX_ARM_SECONDS,
                                           help="Control loop run time (s).")] = 3.0,
    json_out: JsonOpt = False,
) -> None:
    """IK time and success, Ruckig time, and the 500 Hz CAN loop's rate and jitter (the robot's joints and gripper as
    simulated motors: 8 for panda_sim, 7 for damiao_6dof; the JSON's `motors`).

    Example: deploy bench arm --json
    """
    from deploy.bench.arm import bench_arm
    from deploy.rig import load_robot

    with err_console.status(f"bench arm: {samples} IK and Ruckig samples, {seconds:g} s of the CAN loop"):
        data = bench_arm(load_robot(None, robot), samples, seconds)
    if json_out:
        print_json(data)
    else:
        print_rows("arm benchmark", data, digits=4)


@app.command("calibration")
def bench_calibration_cmd(
    seed: StationSeedOpt = 0,
    solver_seeds: Annotated[int, typer.Option("--solver-seeds", min=0, help="Station seeds of the solver comparison "
                                              "(OpenCV's solvers against ours, 15 poses each; 0: skip it).")] = 10,
    json_out: JsonOpt = False,
) -> None:
    """Hand-eye error against simulated truth vs number of poses, depth/colour noise and method (640x480), and
    each solver (OpenCV's and ours) over several station seeds: median / p90 / max.

    Example: deploy bench calibration --solver-seeds 5 --json
    """
    from deploy.bench.calibration import NOMINAL, TARGET_AT_15_POSES, bench_calibration, bench_solvers

    with err_console.status("bench calibration") as status:
        update = lambda what: status.update(f"bench calibration: {what}")  # noqa: E731
        data = bench_calibration(seed=seed, progress=update)
        data["solvers"] = bench_solvers(seeds=range(solver_seeds), progress=update) if solver_seeds else []
    if json_out:
        print_json(data)
        return
    print_table("hand-eye error vs truth (mm / deg), simulated D415 at 640x480",
                ("setup", "noise", "method", "poses", "mm", "deg"),
                [(r["setup"], r["noise"], r["method"], str(r["poses"]), f"{r['translation_mm']:.2f}",
                  f"{r['rotation_deg']:.3f}") for r in data["results"]])
    if data["solvers"]:
        print_table(f"solvers over {solver_seeds} station seeds, 15 poses, {NOMINAL.name} noise: median / p90 / max",
                    ("setup", "method", "source", "mm", "deg"),
                    [(r["setup"], r["method"], r["source"], _three(r, "translation_mm", 2),
                      _three(r, "rotation_deg", 3)) for r in data["solvers"]])
    if (worst := data["worst_at_15_poses"]) is not None:
        mm, deg = TARGET_AT_15_POSES
        console.print(f"worst setup at 15 poses (auto, {NOMINAL.name} noise): {worst['setup']}, "
                      f"{worst['translation_mm']:.2f} mm / {worst['rotation_deg']:.3f} deg (target <= {mm:g} mm and "
                      f"<= {deg:g} deg)")


def _three(row: dict, name: str, digits: int) -> str:
    """`row`'s median / p90 / max of `name`."""
    return " / ".join(f"{row[f'{name}_{stat}']:.{digits}f}" for stat in ("median", "p90", "max"))


def _bench_target(task: Task, distance: float | None, angle: float | None, target: float | None,
                  segmenter: str | None) -> float:
    """The target of `bench open` (m or deg), checked before any episode starts: ConfigError for the other task's
    option, the old --target (alone it still sets the target) beside --distance / --angle, a value the run config
    refuses, or a segmenter the bench cannot feed."""
    from pydantic import ValidationError

    from deploy.errors import ConfigError

    other = "--angle" if task is Task.drawer and angle is not None else \
        "--distance" if task is Task.door and distance is not None else None
    own = "--distance" if task is Task.drawer else "--angle"
    if other is not None:
        raise ConfigError(f"{other} is for the other task, not --task {task.value}: give {own}")
    if target is not None and (distance is not None or angle is not None):
        raise ConfigError(f"--target {target:g} with {own}: --target is the old name of {own} and both set the "
                          f"target: give {own} alone")
    field, option, given = ("target_distance_m", "--distance", distance) if task is Task.drawer else \
        ("target_angle_deg", "--angle", angle)
    if target is not None:
        option = "--target"
    goal = target if target is not None else given if given is not None else getattr(OPENING, field)
    try:
        OpeningConfig(**{field: goal})
    except ValidationError as exc:
        raise ConfigError(f"invalid value for {option}: {goal:g}: {exc.errors()[0]['msg'].lower()}: give a value "
                          "in that range") from None
    if segmenter is not None:
        entry, _ = SEGMENTERS.entry(segmenter)
        if entry not in OPENABLE:
            raise ConfigError(f"--segmenter {segmenter} needs the object's box on each scene's first frame, which "
                              f"bench open cannot give: use {' or '.join(e.name for e in OPENABLE)}")
    return goal
