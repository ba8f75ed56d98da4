"""`deploy bench open`: the success rate of simulated openings (success = the true joint value at the end >= the
target, like the paper), with the failure causes. Each episode is a `deploy open*` request on a simulated rig."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deploy.bench.executors import make_executor
from deploy.control.session import OpenRequest, Setup, open_object
from deploy.perception.registry import default_segmenter

CALIBRATION_ERROR = (5.0, 0.5)  # a field-grade hand-eye calibration: translation mm, rotation deg


def simulate_episode(task: str, seed: int, split: str = "train", target: float | None = None,
                     policy: str = "closed", auto_joint: bool = False, arm: str = "sim",
                     segmenter: str | None = None, calibration_error: tuple[float, float] = CALIBRATION_ERROR,
                     overrides: dict[str, Any] | None = None, run_dir: Path | None = None,
                     setup: Setup | None = None, **options: Any) -> dict:
    """One simulated episode of `task` ("drawer" | "door") on scenario `seed`, `target` in m (drawer) or deg
    (door), with what a real robot senses: `segmenter` (default: the machine's default, `rgbd` without
    weights) and a camera pose calibrated with `calibration_error` (mm, deg). `options` override `[opening]`
    settings, `overrides` any setting by dotted name; `setup(world, arm)` changes the world first (tests).
    The episode's JSON with the truth-based fields."""
    target_field = {"drawer": "distance_m", "door": "angle_deg"}[task]
    request = OpenRequest(task="auto" if auto_joint else task, scene=task, seed=seed, split=split,  # type: ignore
                          policy=policy, arm=arm, run_dir=run_dir, segmenter=segmenter,  # type: ignore[arg-type]
                          calibration_error=tuple(calibration_error),  # type: ignore[arg-type]
                          overrides={**{f"opening.{k}": v for k, v in options.items()}, **(overrides or {})},
                          **({target_field: target} if target is not None else {}))
    return open_object(request, setup=setup, keep_run_dir=run_dir is not None)


def bench_open(
    task: str,
    target: float,
    episodes: int = 10,
    split: str = "test",
    policy: str = "closed",
    seed: int = 0,
    workers: int = 1,
    progress: Callable[[dict], None] | None = None,
    ray_address: str | None = None,
    segmenter: str | None = None,
    calibration_error: tuple[float, float] = CALIBRATION_ERROR,
    **options: Any,
) -> dict:
    """`episodes` consecutive scenario seeds from `seed`; success rate (truth), mean true opening,
    median axis angle error (and, for doors, position error), per-frame perception + geometry time, seconds
    per episode and failure causes {stop_reason: count}. Realistic by default: the machine's default
    segmenter and a calibrated camera pose off by `calibration_error` (mm, deg); the JSON states both.
    Episodes run in `workers` local processes, or on a Ray cluster at `ray_address` (deploy/bench/executors.py)."""
    segmenter = segmenter or default_segmenter()
    unit = "m" if task == "drawer" else "deg"
    jobs = [dict(task=task, seed=s, split=split, target=target, policy=policy, segmenter=segmenter,
                 calibration_error=tuple(calibration_error), **options) for s in range(seed, seed + episodes)]
    results = []
    with make_executor(workers, ray_address) as executor:
        for result in executor.map(simulate_episode, jobs):
            results.append(result)
            if progress is not None:
                progress(result)
    angles = [r["axis_angle_error_deg"] for r in results if r["axis_angle_error_deg"] is not None]
    positions = [r["axis_position_error_m"] for r in results if r["axis_position_error_m"] is not None]
    failures = Counter(r["stop_reason"] if r["stop_reason"] != "target reached" else "short of target (truth)"
                       for r in results if not r["success"])
    frame_ms = [r["timings"]["frame_ms_median"] for r in results if "frame_ms_median" in r["timings"]]
    frame_p90 = [r["timings"]["frame_ms_p90"] for r in results if "frame_ms_p90" in r["timings"]]
    return {
        "task": task, f"target_{unit}": target, "split": split, "policy": policy, "episodes": episodes,
        "segmenter": segmenter,
        "calibration_error": {"translation_mm": calibration_error[0], "rotation_deg": calibration_error[1]},
        "success_rate": float(np.mean([r["success"] for r in results])) if results else 0.0,
        f"mean_opened_{unit}": float(np.mean([r[f"true_opened_{unit}"] for r in results])) if results else 0.0,
        "axis_angle_error_deg_median": float(np.median(angles)) if angles else None,
        "axis_position_error_m_median": float(np.median(positions)) if positions else None,
        "frame_ms_median": float(np.median(frame_ms)) if frame_ms else None,
        "frame_ms_p90_max": float(np.max(frame_p90)) if frame_p90 else None,
        "regrasps": int(sum(r["regrasped"] for r in results)),
        "seconds_per_episode": float(np.mean([r["seconds"] for r in results])) if results else 0.0,
        "failures": dict(failures),
    }
