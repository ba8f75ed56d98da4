"""`deploy bench ...`: accuracy and speed of every area, the numbers in docs/benchmarks.md."""

from __future__ import annotations

from typing import Annotated

import typer

from deploy.commands.options import JsonOpt, PolicyChoice, PolicyOpt, RobotOpt, Split, StationSeedOpt, Task
from deploy.commands.output import console, err_console, fmt, print_json, print_rows, print_table, progress_bar

app = typer.Typer(help="Benchmarks: accuracy and speed, results for docs/benchmarks.md.", no_args_is_help=True)


@app.command("axis")
def bench_axis_cmd(
    sequences: Annotated[int, typer.Option(help="Sequences per object kind.")] = 20,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    json_out: JsonOpt = False,
) -> None:
    """Axis accuracy and speed of every estimator on synthetic D415-like sequences with known axes.

    Example: deploy bench axis --sequences 50 --json
    """
    from deploy.bench.axis import bench_axis

    with progress_bar("bench axis") as bar:
        data = bench_axis(sequences, seed, progress=bar.counts)
    if json_out:
        print_json(data)
        return
    print_table(
        f"axis estimators on {data['sequences']} synthetic sequences (seed {seed})",
        ("estimator", "drawer deg med/p90", "door deg med/p90", "door pos cm med/p90", "joint acc", "failed",
         "ms med"),
        [(name, f"{fmt(s['drawer_angle_deg_median'])} / {fmt(s['drawer_angle_deg_p90'])}",
          f"{fmt(s['door_angle_deg_median'])} / {fmt(s['door_angle_deg_p90'])}",
          f"{fmt(s['door_position_m_median'], 100)} / {fmt(s['door_position_m_p90'], 100)}",
          f"{s['joint_type_accuracy']:.2f}", str(s["failed_estimates"]), fmt(s["ms_median"], digits=1))
         for name, s in data["estimators"].items()],
    )
    console.print(f"full geometry step ({data['step_estimator']}), median: {fmt(data['step_ms_median'], digits=1)} ms")


@app.command("open")
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
    from deploy.bench.open import bench_open

    with progress_bar(f"bench open {task.value}", episodes) as bar:
        data = bench_open(task.value, target, episodes, split.value, policy.value, seed, workers,
                          progress=bar.advance, ray_address=ray, auto_joint=auto_joint)
    if json_out:
        print_json(data)
        return
    print_rows(f"{task.value} to {target} ({split.value}, {policy.value} loop)", data)


@app.command("sim")
def bench_sim_cmd(json_out: JsonOpt = False) -> None:
    """Physics steps per second, render time per frame and the real-time factor of an opening.

    Example: deploy bench sim --json
    """
    from sim_fallback.bench import bench_sim

    data = bench_sim()
    if json_out:
        print_json(data)
        return
    print_rows("simulation speed", data, digits=2)


@app.command("perception")
def bench_perception_cmd(
    seeds: Annotated[int, typer.Option(help="Scenario seeds (a drawer and a door recording each).")] = 1,
    fps: Annotated[float, typer.Option(help="Frames per second of the simulated recordings.")] = 10.0,
    json_out: JsonOpt = False,
) -> None:
    """Per-frame latency of each segmenter backend and its mask IoU against the simulator's oracle masks.

    gdino-sam2 / gdino-edgetam are measured only where their weights are in the local cache (else skipped).
    Example: deploy bench perception --seeds 2 --json
    """
    from deploy.perception.bench import bench_perception

    with progress_bar("bench perception") as bar:
        data = bench_perception(seeds, fps, progress=bar.describe)
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
    print_table(f"segmenters on {data['recordings']} simulated recordings ({data['device']})",
                ("backend", "track ms median", "track ms p90", "start ms", "IoU median", "IoU min", "frames"), rows)


@app.command("arm")
def bench_arm_cmd(
    robot: RobotOpt = None,
    samples: Annotated[int, typer.Option(help="IK and Ruckig samples.")] = 500,
    seconds: Annotated[float, typer.Option(help="Control loop run time (s).")] = 3.0,
    json_out: JsonOpt = False,
) -> None:
    """IK time and success, Ruckig time, and the 500 Hz CAN loop's rate and jitter (8 simulated motors).

    Example: deploy bench arm --json
    """
    from deploy.arm_bringup import load
    from deploy.bench.arm import bench_arm

    data = bench_arm(load(robot), samples, seconds)
    if json_out:
        print_json(data)
    else:
        print_rows("arm benchmark", data, digits=4)


@app.command("calibration")
def bench_calibration_cmd(seed: StationSeedOpt = 0, json_out: JsonOpt = False) -> None:
    """Hand-eye error against simulated truth vs number of poses, depth/colour noise and method (640x480).

    Example: deploy bench calibration --json
    """
    from deploy.bench.calibration import bench_calibration

    with err_console.status("bench calibration") as status:
        data = bench_calibration(seed=seed, progress=lambda what: status.update(f"bench calibration: {what}"))
    if json_out:
        print_json(data)
        return
    print_table("hand-eye error vs truth (mm / deg), simulated D415 at 640x480",
                ("setup", "noise", "method", "poses", "mm", "deg"),
                [(r["setup"], r["noise"], r["method"], str(r["poses"]), f"{r['translation_mm']:.2f}",
                  f"{r['rotation_deg']:.3f}") for r in data["results"]])
    console.print(f"best at 15 poses: {data['best_at_15_poses']}")
