"""Opening episodes in simulation (`deploy bench open`): the policy sees the camera and the arm only;
the world's truth is read AFTER each episode, for evaluation (success = true joint value >= target)."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from deploy.control.episode import run_episode
from deploy.control.policy import OpenConfig, Policy
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.types import Axis
from deploy.perception.oracle import OracleSegmenter
from drivers.arm.trajectory import MotionLimits
from sim_fallback.arm import SimArm
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

Hook = Callable[[SimWorld, SimArm], None]


def simulate_episode(
    task: str,
    seed: int,
    split: str = "train",
    target: float | None = None,
    policy: Policy = "closed",
    run_dir: str | Path | None = None,
    resolution: tuple[int, int] = (640, 480),
    setup: Hook | None = None,
    **options: Any,
) -> dict:
    """One episode of `task` ("drawer" | "door") on scenario `seed`; `target` in m (drawer) or deg (door).

    `options` go to OpenConfig (e.g. fusion="vision"); `setup(world, arm)` may change the world before the
    episode (tests: lock the joint, weaken the grasp). Returns the episode's JSON result plus the truth:
    true_opened (m or deg), axis_angle_error_deg, axis_position_error_m, and success = true value >= target.
    """
    wall = time.perf_counter()
    target_key = "target_distance_m" if task == "drawer" else "target_angle_deg"
    config = OpenConfig(task=task, policy=policy, **({target_key: target} if target is not None else {}), **options)
    with SimWorld(Scenario.make(task, seed, split)) as world:
        arm = SimArm(world)
        camera = SimCamera(world, intrinsics=d415_intrinsics(*resolution), seed=seed, fps=config.camera_hz)
        if setup is not None:
            setup(world, arm)
        truth0 = world.truth()

        def axis_error(axis: Axis) -> tuple[float, float]:  # evaluation only: drawn in the report
            return (axis_angle_error_deg(truth0.direction, axis.direction),
                    axis_position_error_m(truth0.origin, truth0.direction, axis.origin, axis.direction))

        result = run_episode(camera, arm, arm.kin, OracleSegmenter(), config, run_dir,
                             MotionLimits.for_robot(world.robot_spec, arm.kin, 0.3),
                             axis_error)
        true_value = world.truth().value
    out = result.to_dict()
    scale = 1.0 if task == "drawer" else float(np.degrees(1.0))
    angle_err, position_err = axis_error(result.axis) if result.axis is not None else (None, None)
    out.update({
        "task": task, "seed": seed, "split": split, "policy": policy,
        "true_opened": true_value * scale, "success": bool(true_value * scale >= config.target * scale),
        "estimated_success": result.success, "axis_angle_error_deg": angle_err,
        "axis_position_error_m": position_err if task == "door" else None,
        "seconds": time.perf_counter() - wall,
    })
    return out


class LocalExecutor:
    """Runs jobs in local worker processes (in this process when workers <= 1); results in job order."""

    def __init__(self, workers: int = 1) -> None:
        self.workers = max(1, int(workers))

    def map(self, fn: Callable[..., dict], jobs: Iterable[dict]) -> Iterator[dict]:
        jobs = list(jobs)
        if self.workers == 1:
            yield from (fn(**job) for job in jobs)
            return
        with ProcessPoolExecutor(self.workers) as pool:
            yield from pool.map(_call, [fn] * len(jobs), jobs)


def _call(fn: Callable[..., dict], job: dict) -> dict:
    return fn(**job)


def bench_open(
    task: str,
    target: float,
    episodes: int = 10,
    split: str = "test",
    policy: Policy = "closed",
    seed: int = 0,
    workers: int = 1,
    progress: Callable[[dict], None] | None = None,
    **options: Any,
) -> dict:
    """`episodes` consecutive scenario seeds from `seed`; success rate (truth), mean true opening,
    median axis angle error, seconds per episode and failure causes {stop_reason: count}."""
    jobs = [dict(task=task, seed=s, split=split, target=target, policy=policy, **options)
            for s in range(seed, seed + episodes)]
    results = []
    for result in LocalExecutor(workers).map(simulate_episode, jobs):
        results.append(result)
        if progress is not None:
            progress(result)
    angles = [r["axis_angle_error_deg"] for r in results if r["axis_angle_error_deg"] is not None]
    failures = Counter(r["stop_reason"] if r["stop_reason"] != "target reached" else "short of target (truth)"
                       for r in results if not r["success"])
    return {
        "task": task, "target": target, "split": split, "policy": policy, "episodes": episodes,
        "success_rate": float(np.mean([r["success"] for r in results])) if results else 0.0,
        "mean_opened": float(np.mean([r["true_opened"] for r in results])) if results else 0.0,
        "axis_angle_error_deg_median": float(np.median(angles)) if angles else None,
        "seconds_per_episode": float(np.mean([r["seconds"] for r in results])) if results else 0.0,
        "failures": dict(failures),
    }
