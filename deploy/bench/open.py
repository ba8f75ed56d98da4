"""`deploy bench open`: the success rate of simulated openings (success = the true joint value at the end >= the
target, like the paper), with the failure causes. Each episode is a `deploy open*` request on a simulated rig."""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deploy.bench.executors import make_executor
from deploy.config import CALIBRATION_ERROR, OpeningConfig, load_config
from deploy.control.session import OpenRequest, Setup, open_object
from deploy.control.state import StopReason
from deploy.errors import ModelError
from deploy.evaluation import Evaluation
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.types import Axis, JointType
from deploy.perception.bench import missing_weights
from deploy.perception.registry import default_segmenter

log = logging.getLogger(__name__)


def simulate_episode(task: str, seed: int, split: str = "train", target: float | None = None,
                     policy: str | None = None, auto_joint: bool = False, arm: str = "sim",
                     segmenter: str | None = None, calibration_error: tuple[float, float] = CALIBRATION_ERROR,
                     overrides: dict[str, Any] | None = None, run_dir: Path | None = None,
                     setup: Setup | None = None, condition: str = "normal", robot: Path | None = None,
                     **options: Any) -> dict:
    """One simulated episode of `task` ("drawer" | "door") on scenario `seed`, `target` in m (drawer) or deg
    (door), with what a real robot senses: `segmenter` (default: the machine's default, `rgbd` without
    weights) and a camera pose calibrated with `calibration_error` (mm, deg); `policy` None: the config's.
    `options` override `[opening]`
    settings, `overrides` any setting by dotted name; `setup(world, arm)` changes the world first (tests);
    `condition` is the object's joint ("normal", "locked", "stiff"); `robot` the robot config whose arm stands in
    the world (None: the simulated Panda). The episode's JSON with the truth-based fields."""
    target_field = {"drawer": "distance_m", "door": "angle_deg"}[task]
    request = OpenRequest(task="auto" if auto_joint else task, scene=task, seed=seed, split=split,  # type: ignore
                          policy=policy, arm=arm, robot=robot, run_dir=run_dir,  # type: ignore[arg-type]
                          segmenter=segmenter,
                          calibration_error=tuple(calibration_error),  # type: ignore[arg-type]
                          condition=condition,  # type: ignore[arg-type]
                          overrides={**{f"opening.{k}": v for k, v in options.items()}, **(overrides or {})},
                          **({target_field: target} if target is not None else {}))
    truth: list[Axis] = []
    through_base: list[bool] = []
    target_si = OpeningConfig(**({f"target_{target_field}": target} if target is not None else {})).target_for(
        JointType.PRISMATIC if task == "drawer" else JointType.REVOLUTE)

    def set_up(world: Any, arm: Any) -> None:
        truth.append(Evaluation(world).true_axis())
        through_base.append(world.sweep_hits_robot_base(target_si))
        if setup is not None:
            setup(world, arm)

    data = open_object(request, setup=set_up, keep_run_dir=run_dir is not None)
    return {**data, **_vision_alone_errors(data.get("vision_axis"), truth[0]),
            "target_through_robot_base": through_base[0]}


def _vision_alone_errors(vision: dict | None, true_axis: Axis) -> dict:
    """The errors of what vision alone would have acted on last (deg, and m for a hinge), against the truth."""
    if vision is None:
        return {"vision_axis_angle_error_deg": None, "vision_axis_position_error_m": None}
    origin, direction = np.asarray(vision["origin"], float), np.asarray(vision["direction"], float)
    position = axis_position_error_m(true_axis.origin, true_axis.direction, origin, direction) \
        if true_axis.joint_type is JointType.REVOLUTE else None
    return {"vision_axis_angle_error_deg": axis_angle_error_deg(true_axis.direction, direction),
            "vision_axis_position_error_m": position}


def bench_open(
    task: str,
    target: float,
    episodes: int = 10,
    split: str = "test",
    policy: str | None = None,
    seed: int = 0,
    workers: int = 1,
    progress: Callable[[dict], None] | None = None,
    ray_address: str | None = None,
    segmenter: str | None = None,
    calibration_error: tuple[float, float] = CALIBRATION_ERROR,
    condition: str = "normal",
    robot: Path | None = None,
    **options: Any,
) -> dict:
    """`episodes` consecutive scenario seeds from `seed`; success rate (truth), mean true opening,
    median axis angle error (and, for doors, position error), per-frame perception + geometry time, seconds
    per episode and failure causes {stop_reason: count}. Realistic by default: the machine's default
    segmenter and a calibrated camera pose off by `calibration_error` (mm, deg); the JSON states both.
    `robot`: the robot config whose arm stands in the world (None: the simulated Panda's, panda_sim).
    `condition`: every object's joint "normal", "locked" or "stiff" (3x the friction); the largest force any
    pull applied is `peak_pull_force_n_max` (N), over the `peak_pull_force_episodes` that pulled (`_pull_forces`).
    Episodes run in `workers` local processes (a warning when more than this machine's cores: the timings then
    include waiting for one), or on a Ray cluster at `ray_address` (deploy/bench/executors.py; `workers` is then
    None in the JSON). `policy` None: the config's default. Run locally, a segmenter whose model weights are not on
    this machine is a ModelError before any episode, naming each missing model and its fetch command (a cluster's
    workers look on their own disks)."""
    perception = load_config(None, options.get("overrides")).perception
    segmenter = segmenter or default_segmenter(perception)
    if ray_address is None and (missing := missing_weights(segmenter, perception)):  # a cluster has its own disks
        raise ModelError(f"--segmenter {segmenter} needs model weights this machine does not have: "
                         f"{', '.join(missing)}; fetch them, or use --segmenter rgbd (no weights)")
    if ray_address is None:
        _warn_above_cores(min(workers, episodes))
    policy = policy or OpeningConfig().policy
    unit = "m" if task == "drawer" else "deg"
    jobs = [dict(task=task, seed=s, split=split, target=target, policy=policy, segmenter=segmenter,
                 calibration_error=tuple(calibration_error), condition=condition, robot=robot, **options)
            for s in range(seed, seed + episodes)]
    results = []
    with make_executor(workers, ray_address) as executor:
        for result in executor.map(simulate_episode, jobs):
            results.append(result)
            if progress is not None:
                progress(result)
    angles = [r["axis_angle_error_deg"] for r in results if r["axis_angle_error_deg"] is not None]
    positions = [r["axis_position_error_m"] for r in results if r["axis_position_error_m"] is not None]
    failed = _failed_seeds(results)
    frame_ms = [r["timings"]["frame_ms_median"] for r in results if "frame_ms_median" in r["timings"]]
    frame_p90 = [r["timings"]["frame_ms_p90"] for r in results if "frame_ms_p90" in r["timings"]]
    frame_cpu = [r["timings"]["frame_cpu_ms_median"] for r in results if "frame_cpu_ms_median" in r["timings"]]
    return {
        "task": task, f"target_{unit}": target, "split": split, "policy": policy, "episodes": episodes,
        "first_seed": seed, "workers": workers if ray_address is None else None,
        "joint": "auto" if options.get("auto_joint") else "told",
        "segmenter": segmenter, "condition": condition, "robot": str(robot or "panda_sim"),
        "calibration_error": {"translation_mm": calibration_error[0], "rotation_deg": calibration_error[1]},
        "success_rate": float(np.mean([r["success"] for r in results])) if results else 0.0,
        **_reachable(results),
        f"mean_opened_{unit}": float(np.mean([r[f"true_opened_{unit}"] for r in results])) if results else 0.0,
        "axis_angle_error_deg_median": float(np.median(angles)) if angles else None,
        "axis_position_error_m_median": float(np.median(positions)) if positions else None,
        **_acted_on_vs_vision_alone(results),
        "frame_ms_median": float(np.median(frame_ms)) if frame_ms else None,
        "frame_ms_p90_max": float(np.max(frame_p90)) if frame_p90 else None,
        "frame_cpu_ms_median": float(np.median(frame_cpu)) if frame_cpu else None,
        "frame_cpu_ms_median_max": float(np.max(frame_cpu)) if frame_cpu else None,
        "regrasps": int(sum(r["regrasped"] for r in results)),
        **_pull_forces(results),
        "seconds_per_episode": float(np.mean([r["seconds"] for r in results])) if results else 0.0,
        "failures": {cause: len(seeds) for cause, seeds in failed.items()},
        "failed_seeds": failed,
    }


def _warn_above_cores(workers: int) -> None:
    """One warning line when `workers` processes are more than the cores this process may use."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    if workers > cores:
        log.warning("--workers %d is above this machine's %d cores: episodes wait for a core, so their seconds and "
                    "frame times include that waiting; give --workers %d or fewer for timings", workers, cores, cores)


def _pull_forces(results: list[dict]) -> dict:
    """The peak pull force's median and max (N) over the episodes that pulled (`peak_pull_force_episodes`): one
    that stopped before its first pull has no pull force, and counting it as 0 N would pull the median down."""
    forces = [r["peak_pull_force_n"] for r in results if r["peak_pull_force_n"] > 0.0]
    return {"peak_pull_force_episodes": len(forces),
            "peak_pull_force_n_median": float(np.median(forces)) if forces else None,
            "peak_pull_force_n_max": float(np.max(forces)) if forces else None}


def _failed_seeds(results: list[dict]) -> dict[str, list[int]]:
    """The seeds of the failed episodes by cause (as `failures` counts them): each can be run alone again."""
    seeds: dict[str, list[int]] = {}
    for r in results:
        if not r["success"]:
            cause = r["stop_reason"] if r["stop_reason"] != StopReason.TARGET_REACHED else "short of target (truth)"
            seeds.setdefault(cause, []).append(r["seed"])
    return seeds


def _reachable(results: list[dict]) -> dict:
    """How many episodes' targets no arm posture reaches (the part would sweep through the robot's base: a door
    hinged close to the robot) and the success rate over the others."""
    reachable = [r for r in results if not r["target_through_robot_base"]]
    return {"episodes_target_through_robot_base": len(results) - len(reachable),
            "success_rate_reachable": float(np.mean([r["success"] for r in reachable])) if reachable else None}


def _acted_on_vs_vision_alone(results: list[dict]) -> dict:
    """Axis errors of the estimate the loop acted on and of what vision alone would have acted on, over the same
    episodes (those with both): median and p90 of the angle (deg) and, for doors, the position (m)."""
    both = [r for r in results
            if r["axis_angle_error_deg"] is not None and r["vision_axis_angle_error_deg"] is not None]
    out: dict[str, Any] = {"axis_error_episodes_compared": len(both)}
    for who, prefix in (("acted_on", "axis"), ("vision_alone", "vision_axis")):
        for kind in ("angle_error_deg", "position_error_m"):
            values = [r[f"{prefix}_{kind}"] for r in both if r[f"{prefix}_{kind}"] is not None]
            for name, q in (("median", 50), ("p90", 90)):
                out[f"{who}_axis_{kind}_{name}"] = float(np.percentile(values, q)) if values else None
    return out
