"""The `deploy` command line: thin typer commands that parse, load the config, call one function, print.

Heavy libraries are imported inside the commands so `deploy --help` stays instant.
"""

from __future__ import annotations

import json
import os
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS threads busy-wait on small machines

import typer
from rich.console import Console
from rich.table import Table

from deploy.errors import USER_ERRORS

console = Console()
err_console = Console(stderr=True)

app = typer.Typer(
    name="deploy", help="axisloop: open drawers and doors by estimating the joint axis online from RGB-D video.",
    no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
)
axis_app = typer.Typer(help="Estimate joint axes from recordings, gripper trajectories or synthetic scenes.",
                       no_args_is_help=True)
sim_app = typer.Typer(help="PyBullet simulation: render scenes and record scripted openings.", no_args_is_help=True)
bench_app = typer.Typer(help="Benchmarks: accuracy and speed, results for docs/benchmarks.md.", no_args_is_help=True)
app.add_typer(axis_app, name="axis")
app.add_typer(sim_app, name="sim")
app.add_typer(bench_app, name="bench")


class JointChoice(str, Enum):
    auto = "auto"
    prismatic = "prismatic"
    revolute = "revolute"


class EstimatorChoice(str, Enum):
    paper_obb = "paper-obb"
    screw = "screw"
    screw_grip = "screw-grip"
    trajectory = "trajectory"


class Task(str, Enum):
    drawer = "drawer"
    door = "door"


class Split(str, Enum):
    train = "train"
    test = "test"


JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")]
ConfigOpt = Annotated[Path | None, typer.Option("--config", help="TOML config file (see docs/cli.md).")]


def _print_json(data: dict) -> None:
    sys.stdout.write(json.dumps(data, indent=2) + "\n")


def print_rows(title: str, rows: dict, digits: int | None = 3) -> None:
    """`rows` as a two-column table: floats with `digits` decimals (None: as they are), None as "-"."""
    table = Table(title=title, show_header=False)
    for key, value in rows.items():
        text = "-" if value is None else f"{value:.{digits}f}" if isinstance(value, float) and digits is not None \
            else str(value)
        table.add_row(key, text)
    console.print(table)


def _fmt(value: float | None, scale: float = 1.0, digits: int = 2) -> str:
    return "-" if value is None else f"{value * scale:.{digits}f}"


def _axis_table(title: str, data: dict) -> Table:
    table = Table(title=title, show_header=False)
    for key in ("joint_type", "origin", "direction", "radius", "residual_m", "n_samples", "estimator", "reason"):
        if key in data and data[key] is not None:
            value = data[key]
            if isinstance(value, list):
                value = "[" + ", ".join(f"{v:+.4f}" for v in value) + "]"
            elif isinstance(value, float):
                value = f"{value:.4f}"
            table.add_row(key, str(value))
    return table


# --- axis -------------------------------------------------------------------------------------------------


@axis_app.command("fit-trajectory")
def axis_fit_trajectory(
    file: Annotated[Path, typer.Argument(help="One sample per line: `x y z` or `x y z qx qy qz qw` (m).")],
    joint: Annotated[JointChoice, typer.Option(help="Joint type, or auto to choose by BIC.")] = JointChoice.auto,
    json_out: JsonOpt = False,
) -> None:
    """Fit a prismatic line or a revolute axis to a gripper (handle) trajectory.

    Example: deploy axis fit-trajectory handle.txt --joint auto --json
    """
    from deploy.errors import RecordingError
    from deploy.geometry.estimators.trajectory import fit_trajectory, parse_trajectory_text
    from deploy.geometry.types import JointType

    if not file.is_file():
        raise RecordingError(f"trajectory file {file} not found: give a text file with one `x y z` per line")
    try:
        positions, quats = parse_trajectory_text(file.read_text())
    except ValueError as exc:
        raise RecordingError(f"trajectory file {file}: {exc}") from exc
    result = fit_trajectory(positions, quats, None if joint == JointChoice.auto else JointType(joint.value))
    data = {"joint_type": None, "origin": None, "direction": None, "radius": None, "residual_m": None,
            "n_samples": len(positions)}
    if hasattr(result, "reason"):
        data["reason"] = result.reason
    else:
        data.update({k: v for k, v in result.to_dict().items() if k in data})
    if json_out:
        _print_json(data)
    else:
        console.print(_axis_table(f"axis fitted to {file}", data))
    if "reason" in data:
        raise typer.Exit(1)


@axis_app.command("estimate")
def axis_estimate(
    recording: Annotated[Path, typer.Argument(help="Frames directory with masks (docs/recording-format.md).")],
    joint: Annotated[JointChoice, typer.Option(help="Joint type, or auto to classify.")] = JointChoice.auto,
    estimator: Annotated[EstimatorChoice | None, typer.Option(
        help="Axis estimator \\[default: screw-grip; without gripper poses in the recording it is screw].")] = None,
    filter_profile: Annotated[str | None, typer.Option("--filter", help="Filter profile: sim or sparse.")] = None,
    filter_radius: Annotated[float | None, typer.Option(help="Filter radius, in --filter-unit.")] = None,
    filter_eps: Annotated[int | None, typer.Option(help="Minimum number of other points within the radius.")] = None,
    filter_unit: Annotated[str | None, typer.Option(help="Unit of --filter-radius: m, cm or mm.")] = None,
    config: ConfigOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Estimate the joint axis from a recording, re-estimating over a sliding window at every frame.

    Examples:
      deploy axis estimate runs/drawer --json
      deploy axis estimate rec/ --estimator paper-obb --joint prismatic --filter sparse
    """
    from deploy.config import load_config
    from deploy.estimate_recording import estimate_recording

    cfg = load_config(config, {
        "estimator.name": estimator.value if estimator else None,
        "estimator.joint": joint.value if joint != JointChoice.auto else None,
        "filter.profile": filter_profile, "filter.radius": filter_radius, "filter.eps": filter_eps,
        "filter.unit": filter_unit,
    })
    data = estimate_recording(recording, cfg)
    if json_out:
        _print_json(data)
    else:
        console.print(_axis_table(f"axis of {recording} ({data['frame']} frame)", data))
    if data["joint_type"] is None:
        raise typer.Exit(1)


@axis_app.command("demo")
def axis_demo(seed: Annotated[int, typer.Option(help="Random seed of the synthetic scenes.")] = 0) -> None:
    """Synthetic noisy drawer and door: every estimator's axis error in one table.

    Example: deploy axis demo --seed 3
    """
    from deploy.bench.axis import demo_axis

    table = Table(title="axis estimators on a synthetic drawer (10 cm) and door (20 deg), D415-like noise")
    for col in ("object", "estimator", "angle error (deg)", "position error (cm)", "auto joint type", "ms"):
        table.add_column(col)
    for r in demo_axis(seed):
        ms = sum(r.ms_per_estimate) / max(len(r.ms_per_estimate), 1)
        table.add_row(r.kind, r.estimator, _fmt(r.angle_deg) if r.angle_deg is not None else f"- ({r.reason})",
                      _fmt(r.position_m, 100), "ok" if r.joint_type_ok else "wrong", f"{ms:.1f}")
    console.print(table)


# --- open -------------------------------------------------------------------------------------------------


class PolicyChoice(str, Enum):
    closed = "closed"
    open = "open"
    paper = "paper"


def _print_episode(data: dict, json_out: bool) -> None:
    if json_out:
        _print_json(data)
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


SeedOpt = Annotated[int, typer.Option(help="Simulated scenario seed (--camera sim).")]
CameraOpt = Annotated[str, typer.Option(help="sim | d415 | d415:SERIAL | replay:PATH (frames dir, .bag, .db3).")]
ArmOpt = Annotated[str, typer.Option(help="sim | sim-can (simulated motors over a virtual CAN bus) | can.")]
RobotOpt = Annotated[Path | None, typer.Option(help="Robot config TOML for --arm can (see docs/arm.md).")]
CalibrationOpt = Annotated[Path | None, typer.Option(
    help="Hand-eye calibration file \\[default: the one saved for this camera and robot].")]
SegmenterOpt = Annotated[str | None, typer.Option(
    help="oracle | gdino-sam2 | classical \\[default: oracle in simulation, gdino-sam2 otherwise].")]
PolicyOpt = Annotated[PolicyChoice, typer.Option(help="closed (re-estimate every step), open or paper.")]
RunDirOpt = Annotated[Path | None, typer.Option(help="Run folder \\[default: runs/TASK-TIME].")]
SplitOpt = Annotated[Split, typer.Option(help="Object family (--camera sim).")]
DryRunOpt = Annotated[bool, typer.Option("--dry-run", help="Perceive and plan the grasp; move nothing.")]
YesOpt = Annotated[bool, typer.Option("--yes", help="Skip the confirmation before a real arm's first motion.")]
ViewOpt = Annotated[bool, typer.Option("--view", help="Stream frames, clouds and axes to a rerun viewer.")]


@app.command("open-drawer")
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


@app.command("open-door")
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


@app.command("open")
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


# --- sim --------------------------------------------------------------------------------------------------


@sim_app.command("show")
def sim_show(
    task: Annotated[Task, typer.Option(help="Cabinet with a drawer or a door.")] = Task.drawer,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    split: Annotated[Split, typer.Option(help="Object family.")] = Split.train,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("scene.png"),
) -> None:
    """Render a simulated scene: colour, depth and segmentation side by side.

    Example: deploy sim show --task door --seed 3 --out door.png
    """
    from sim_fallback.show import render_scene_png

    render_scene_png(task.value, seed, out, split=split.value)
    console.print(f"wrote {out}")


@sim_app.command("record")
def sim_record(
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    task: Annotated[Task, typer.Option(help="Cabinet with a drawer or a door.")] = Task.drawer,
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    split: Annotated[Split, typer.Option(help="Object family.")] = Split.train,
    fps: Annotated[float, typer.Option(help="Camera frames per second.")] = 10.0,
) -> None:
    """Record a scripted opening (a data generator that uses ground truth, not the policy).

    Writes the frames-directory format with masks, poses and truth.json.
    Example: deploy sim record --task drawer --seed 1 --out runs/drawer1 && deploy axis estimate runs/drawer1
    """
    from sim_fallback.scripted import record_scripted

    summary = record_scripted(task.value, seed, out, split=split.value, fps=fps)
    console.print(f"wrote {out}: {summary}")


# --- bench ------------------------------------------------------------------------------------------------


@bench_app.command("axis")
def bench_axis_cmd(
    sequences: Annotated[int, typer.Option(help="Sequences per object kind.")] = 20,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    json_out: JsonOpt = False,
) -> None:
    """Axis accuracy and speed of every estimator on synthetic D415-like sequences with known axes.

    Example: deploy bench axis --sequences 50 --json
    """
    from rich.progress import Progress

    from deploy.bench.axis import bench_axis

    with Progress(console=err_console, transient=True) as bar:
        job = bar.add_task("bench axis", total=None)
        data = bench_axis(sequences, seed, progress=lambda done, total: bar.update(job, completed=done, total=total))
    if json_out:
        _print_json(data)
        return
    table = Table(title=f"axis estimators on {data['sequences']} synthetic sequences (seed {seed})")
    for col in ("estimator", "drawer deg med/p90", "door deg med/p90", "door pos cm med/p90", "joint acc",
                "failed", "ms med"):
        table.add_column(col)
    for name, s in data["estimators"].items():
        table.add_row(
            name, f"{_fmt(s['drawer_angle_deg_median'])} / {_fmt(s['drawer_angle_deg_p90'])}",
            f"{_fmt(s['door_angle_deg_median'])} / {_fmt(s['door_angle_deg_p90'])}",
            f"{_fmt(s['door_position_m_median'], 100)} / {_fmt(s['door_position_m_p90'], 100)}",
            f"{s['joint_type_accuracy']:.2f}", str(s["failed_estimates"]), _fmt(s["ms_median"], digits=1),
        )
    console.print(table)
    console.print(f"full geometry step ({data['step_estimator']}), median: {_fmt(data['step_ms_median'], digits=1)} ms")


@bench_app.command("open")
def bench_open_cmd(
    task: Annotated[Task, typer.Option(help="drawer or door.")] = Task.drawer,
    target: Annotated[float, typer.Option(help="Target opening: m (drawer) or deg (door).")] = 0.30,
    episodes: Annotated[int, typer.Option(help="Episodes (consecutive scenario seeds).")] = 10,
    split: Annotated[Split, typer.Option(help="Object family.")] = Split.test,
    policy: PolicyOpt = PolicyChoice.closed,
    seed: Annotated[int, typer.Option(help="First scenario seed.")] = 0,
    workers: Annotated[int, typer.Option(help="Local worker processes.")] = 1,
    ray: Annotated[str | None, typer.Option(
        "--ray", metavar="ADDRESS", help="Run episodes on a Ray cluster: local, auto, ray://HOST:10001 or "
        "HOST:6379 (needs the cluster extra); --workers is then unused.")] = None,
    auto_joint: Annotated[bool, typer.Option(
        "--auto-joint", help="The policy is not told the task: it classifies from its probe pull.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Success rate of simulated openings (success = the true joint value exceeds the target, like the paper).

    Example: deploy bench open --task door --target 45 --episodes 20 --workers 2 --json
    Example: deploy bench open --task drawer --target 0.30 --episodes 1000 --ray ray://head:10001 --json
    """
    from rich.progress import Progress

    from deploy.bench.open import bench_open

    with Progress(console=err_console, transient=True) as bar:
        job = bar.add_task(f"bench open {task.value}", total=episodes)
        data = bench_open(task.value, target, episodes, split.value, policy.value, seed, workers,
                          progress=lambda _result: bar.advance(job), ray_address=ray,
                          auto_joint=auto_joint)
    if json_out:
        _print_json(data)
        return
    print_rows(f"{task.value} to {target} ({split.value}, {policy.value} loop)", data)


@bench_app.command("sim")
def bench_sim_cmd(json_out: JsonOpt = False) -> None:
    """Physics steps per second, render time per frame and the real-time factor of an opening.

    Example: deploy bench sim --json
    """
    from sim_fallback.bench import bench_sim

    data = bench_sim()
    if json_out:
        _print_json(data)
        return
    print_rows("simulation speed", data, digits=2)


from deploy.commands import arm, calibrate, cameras, perception  # noqa: E402  (they add to the apps above)

for _area in (perception, cameras, arm, calibrate):
    _area.register(app, bench_app)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `deploy` script; returns the exit code. User errors become one red line (code 2)."""
    try:
        app(args=argv, prog_name="deploy")
    except SystemExit as exc:  # typer's standalone mode always ends here: usage errors, --help, Exit
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except USER_ERRORS as exc:
        err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
