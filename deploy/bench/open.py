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
from deploy.rig import load_robot
from drivers.arm.robots import Reach
from sim_fallback.errors import SceneError
from sim_fallback.partnet import PartNetError
from sim_fallback.scenes import check_scene, load_object, task_objects

log = logging.getLogger(__name__)


def simulate_episode(task: str, seed: int, split: str = "train", target: float | None = None,
                     policy: str | None = None, auto_joint: bool = False, arm: str = "sim",
                     segmenter: str | None = None, calibration_error: tuple[float, float] = CALIBRATION_ERROR,
                     overrides: dict[str, Any] | None = None, run_dir: Path | None = None,
                     setup: Setup | None = None, condition: str = "normal", world: str = "kitchen",
                     part: str | None = None, assets: Path | None = None, object_id: str | None = None,
                     scale: str = "real", robot: Path | None = None,
                     **options: Any) -> dict:
    """One simulated episode of `task` ("drawer" | "door") on scenario `seed` of `world` ("kitchen" or "box"),
    `target` in m (drawer) or deg (door), with what a real robot senses: `segmenter` (default: the machine's
    default, `rgbd` without weights), a camera pose calibrated with `calibration_error` (mm, deg) and the simulated
    user's pixel on the part; `policy` None: the config's. `part`, `assets`, `object_id`, `scale`: the part and
    PartNet-Mobility object (`deploy.rig.SimScene`). `options` override `[opening]` settings, `overrides` any
    setting by dotted name; `setup(world, arm)` changes the world first (tests); `condition` is the object's joint
    ("normal", "locked", "stiff"); `robot` the robot config whose arm stands in the world (None: the simulated
    Panda). The episode's JSON with the truth-based fields."""
    target_field = {"drawer": "distance_m", "door": "angle_deg"}[task]
    request = OpenRequest(task="auto" if auto_joint else task, scene=task, seed=seed, split=split,  # type: ignore
                          policy=policy, arm=arm, robot=robot, run_dir=run_dir,  # type: ignore[arg-type]
                          segmenter=segmenter,
                          calibration_error=tuple(calibration_error),  # type: ignore[arg-type]
                          condition=condition,  # type: ignore[arg-type]
                          world=world, part=part, assets=assets, object_id=object_id, scale=scale,
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
    world: str = "kitchen",
    part: str | None = None,
    assets: Path | None = None,
    object_id: str | None = None,
    scale: str = "real",
    **options: Any,
) -> dict:
    """`episodes` consecutive scenario seeds from `seed` in `world`; success rate (truth), mean true opening,
    median axis angle error (and, for doors, position error), per-frame perception + geometry time, seconds
    per episode and failure causes {stop_reason: count}, and the success and failures per part (`per_part`).
    `robot`: the robot config whose arm stands in the world (None: the simulated Panda's, panda_sim).
    Realistic by default: the machine's default segmenter, a calibrated camera pose off by `calibration_error` (mm,
    deg), the simulated user's pixel on the part as the only word about it, the sensor models of every simulated
    episode (`sensors`); the JSON states them. `part`: every episode's part (None: the seed's). `assets`: a folder
    of PartNet-Mobility objects, `object_id` one of them (None: the usable ones cycled by seed) at `scale`; the
    results per object (`objects`) and why each other object cannot be used (`unusable_objects`). An episode whose
    scene cannot be built counts as failed, "not placed". `condition`: every object's joint "normal", "locked" or
    "stiff" (3x the friction); the largest force any pull applied is `peak_pull_force_n_max` (N), over the
    `peak_pull_force_episodes` that pulled (`_pull_forces`). Episodes run in `workers` local processes (a warning
    when more than this machine's cores: the timings then include waiting for one), or on a Ray cluster at
    `ray_address` (deploy/bench/executors.py; `workers` is then None in the JSON). `policy` None: the config's
    default. Run locally, a segmenter whose model weights are not on this machine is a ModelError before any
    episode, naming each missing model and its fetch command (a cluster's workers look on their own disks)."""
    perception = load_config(None, options.get("overrides")).perception
    segmenter = segmenter or default_segmenter(perception)
    if ray_address is None and (missing := missing_weights(segmenter, perception)):  # a cluster has its own disks
        raise ModelError(f"--segmenter {segmenter} needs model weights this machine does not have: "
                         f"{', '.join(missing)}; fetch them, or use --segmenter rgbd (no weights)")
    if ray_address is None:
        _warn_above_cores(min(workers, episodes))
    policy = policy or OpeningConfig().policy
    reach = load_robot("sim", robot).reach.reach()
    opening = target if task == "drawer" else float(np.radians(target))
    objects, unusable = _objects(task, range(seed, seed + episodes), world, assets, object_id, scale, reach, opening)
    scene = dict(world=world, part=part, assets=assets, scale=scale)
    jobs = [dict(task=task, seed=s, split=split, target=target, policy=policy, segmenter=segmenter,
                 calibration_error=tuple(calibration_error), condition=condition, robot=robot, object_id=objects[s],
                 **scene,
                 **options) for s in range(seed, seed + episodes)]
    results = []
    with make_executor(workers, ray_address) as executor:
        for result in executor.map(bench_episode, jobs):
            results.append(result)
            if progress is not None:
                progress(result)
    return {
        "task": task, f"target_{'m' if task == 'drawer' else 'deg'}": target, "split": split, "policy": policy,
        "episodes": episodes, "first_seed": seed, "workers": workers if ray_address is None else None,
        "joint": "auto" if options.get("auto_joint") else "told", "segmenter": segmenter, "condition": condition,
        "robot": str(robot or "panda_sim"),
        "calibration_error": {"translation_mm": calibration_error[0], "rotation_deg": calibration_error[1]},
        "world": world, "assets": None if assets is None else str(assets), "part": part,
        "scale": scale if assets is not None else None, "pointer": POINTER if world != "box" else None,
        "sensors": _sensors(results),
        **_rates(task, results), "per_part": _per_part(results),
        **({"objects": _per_object(results), "unusable_objects": unusable} if assets is not None else {}),
    }


POINTER = "simulated user: one pixel on the target part's front in the first frame"
NOT_PLACED = "not placed"  # the stop reason of an episode whose scene could not be built


def bench_episode(**job: Any) -> dict:
    """`simulate_episode(**job)`; a scene that cannot be built (the part out of reach, no room to park the robot, no
    camera position that sees the part) is a failed episode "not placed" with its one-line reason."""
    try:
        return simulate_episode(**job)
    except SceneError as exc:
        return {"seed": job["seed"], "object": job.get("object_id"), "part": job.get("part"), "success": False,
                "stop_reason": NOT_PLACED, "message": str(exc)}


def _objects(task: str, seeds: range, world: str, assets: Path | None, object_id: str | None,
             scale: str, reach: Reach, opening: float) -> tuple[dict[int, str | None], dict[str, str]]:
    """The PartNet-Mobility object of each seed (None without `assets`) and why each other object of the folder
    cannot be used by an arm of `reach` to open a part `opening` (m or rad); one-line errors before any episode for
    a bad folder, object or world."""
    check_scene(world, assets, object_id)
    if assets is None:
        return dict.fromkeys(seeds), {}
    choice = task_objects(assets, task, scale, reach, opening)
    if object_id is not None:
        load_object(assets, object_id, scale)  # one line when it is not there or does not load
        if object_id in choice.problems:
            raise PartNetError(choice.problems[object_id])
        return dict.fromkeys(seeds, object_id), {}
    return {s: choice.for_seed(s) for s in seeds}, choice.problems


def _rates(task: str, results: list[dict]) -> dict:
    """The success rate over every episode, and over the episodes that ran: the means, medians and counts."""
    unit = "m" if task == "drawer" else "deg"
    ran = [r for r in results if r["stop_reason"] != NOT_PLACED]
    angles = [r["axis_angle_error_deg"] for r in ran if r["axis_angle_error_deg"] is not None]
    positions = [r["axis_position_error_m"] for r in ran if r["axis_position_error_m"] is not None]
    failed = _failed_seeds(results)
    frame_ms = [r["timings"]["frame_ms_median"] for r in ran if "frame_ms_median" in r["timings"]]
    frame_p90 = [r["timings"]["frame_ms_p90"] for r in ran if "frame_ms_p90" in r["timings"]]
    frame_cpu = [r["timings"]["frame_cpu_ms_median"] for r in ran if "frame_cpu_ms_median" in r["timings"]]
    return {
        "success_rate": float(np.mean([r["success"] for r in results])) if results else 0.0,
        "episodes_not_placed": len(results) - len(ran),
        **_reachable(ran),
        f"mean_opened_{unit}": float(np.mean([r[f"true_opened_{unit}"] for r in ran])) if ran else 0.0,
        "axis_angle_error_deg_median": float(np.median(angles)) if angles else None,
        "axis_position_error_m_median": float(np.median(positions)) if positions else None,
        **_acted_on_vs_vision_alone(ran),
        "frame_ms_median": float(np.median(frame_ms)) if frame_ms else None,
        "frame_ms_p90_max": float(np.max(frame_p90)) if frame_p90 else None,
        "frame_cpu_ms_median": float(np.median(frame_cpu)) if frame_cpu else None,
        "frame_cpu_ms_median_max": float(np.max(frame_cpu)) if frame_cpu else None,
        "regrasps": int(sum(r["regrasped"] for r in ran)),
        **_pull_forces(ran),
        "seconds_per_episode": float(np.mean([r["seconds"] for r in ran])) if ran else 0.0,
        "failures": {cause: len(seeds) for cause, seeds in failed.items()},
        "failed_seeds": failed,
    }


def _sensors(results: list[dict]) -> dict | None:
    """The sensor models every episode measured with (each draws its own pad friction in the range)."""
    for r in results:
        if "sensors" in r:
            return {k: v for k, v in r["sensors"].items() if k != "pad_friction"}
    return None


def _tally(results: list[dict]) -> dict:
    """Episodes, successes, success rate and failures by cause of `results`."""
    causes: dict[str, int] = {}
    for r in results:
        if not r["success"]:
            cause = _cause(r)
            causes[cause] = causes.get(cause, 0) + 1
    successes = sum(r["success"] for r in results)
    return {"episodes": len(results), "successes": successes,
            "success_rate": successes / len(results) if results else 0.0, "failures": causes}


def _per_part(results: list[dict]) -> dict:
    """`_tally` by the part opened (its name; None: not placed, the part unknown)."""
    parts: dict[str, list[dict]] = {}
    for r in results:
        parts.setdefault(str(r.get("part")), []).append(r)
    return {name: _tally(group) for name, group in sorted(parts.items())}


def _per_object(results: list[dict]) -> dict:
    """`_tally` by PartNet-Mobility object, each with its `parts` tallied too."""
    objects: dict[str, list[dict]] = {}
    for r in results:
        objects.setdefault(str(r.get("object")), []).append(r)
    return {name: {**_tally(group), "parts": _per_part(group)} for name, group in objects.items()}


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
            seeds.setdefault(_cause(r), []).append(r["seed"])
    return seeds


def _cause(result: dict) -> str:
    """Why a failed episode failed: its stop reason, or "short of target (truth)" when the controller thought it
    had reached the target."""
    return result["stop_reason"] if result["stop_reason"] != StopReason.TARGET_REACHED else "short of target (truth)"


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
