"""Opening episodes in simulation (`deploy bench open`): the policy sees the camera and the arm only;
the world's truth is read AFTER each episode, for evaluation (success = true joint value >= target)."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deploy.bench.executors import make_executor
from deploy.control.episode import run_episode
from deploy.control.policy import OpenConfig, Policy
from deploy.control.viewer import RerunViewer
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.types import Axis, JointType
from deploy.perception.oracle import OracleSegmenter
from drivers.arm.base import Arm
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from sim_fallback.arm import SimArm
from sim_fallback.arm_factory import PANDA_SIM_CONFIG, open_arm
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
    auto_joint: bool = False,
    view: bool = False,
    arm_kind: str = "sim",
    **options: Any,
) -> dict:
    """One episode of `task` ("drawer" | "door") on scenario `seed`; `target` in m (drawer) or deg (door).

    arm_kind: "sim" (the PyBullet arm directly) or "sim-can" (the CAN driver talking to simulated Damiao
    motors on a virtual bus, which move the same PyBullet arm; configs/robots/panda_sim.toml).
    view: stream to a rerun viewer and save RUN/episode.rrd (needs run_dir).
    auto_joint: the policy is not told the joint type and classifies it from the first pull.
    `options` go to OpenConfig (e.g. fusion="vision"); `setup(world, arm)` may change the world before the
    episode (tests: lock the joint, weaken the grasp). Returns the episode's JSON result plus the truth:
    true_opened (m or deg), axis_angle_error_deg, axis_position_error_m, and success = true value >= target.
    """
    wall = time.perf_counter()
    target_key = "target_distance_m" if task == "drawer" else "target_angle_deg"
    config = OpenConfig(task="auto" if auto_joint else task, policy=policy,
                        **({target_key: target} if target is not None else {}), **options)
    with SimWorld(Scenario.make(task, seed, split)) as world, _sim_arm(arm_kind, world) as arm:
        camera = SimCamera(world, intrinsics=d415_intrinsics(*resolution), seed=seed, fps=config.camera_hz)
        if setup is not None:
            setup(world, arm)
        truth0 = world.truth()

        def axis_error(axis: Axis) -> tuple[float, float]:  # evaluation only: drawn in the report
            return (axis_angle_error_deg(truth0.direction, axis.direction),
                    axis_position_error_m(truth0.origin, truth0.direction, axis.origin, axis.direction))

        result = run_episode(camera, arm, arm.kin, OracleSegmenter(), config, run_dir,
                             MotionLimits.for_robot(world.robot_spec, arm.kin, 0.3),
                             axis_error, RerunViewer(Path(run_dir) / "episode.rrd") if view and run_dir else None)
        true_value = world.truth().value
    out = result.to_dict()
    scale = 1.0 if task == "drawer" else float(np.degrees(1.0))
    angle_err, position_err = axis_error(result.axis) if result.axis is not None else (None, None)
    out.update({
        "task": task, "seed": seed, "split": split, "policy": policy,
        "true_opened": true_value * scale,
        "success": bool(true_value >= config.target_for(JointType(truth0.joint_type))),
        "estimated_success": result.success, "axis_angle_error_deg": angle_err,
        "axis_position_error_m": position_err if task == "door" else None,
        "seconds": time.perf_counter() - wall,
    })
    return out


def _sim_arm(kind: str, world: SimWorld) -> Arm:
    if kind == "sim":
        return SimArm(world)
    return open_arm(kind, load_robot_config(PANDA_SIM_CONFIG), world)


def bench_open(
    task: str,
    target: float,
    episodes: int = 10,
    split: str = "test",
    policy: Policy = "closed",
    seed: int = 0,
    workers: int = 1,
    progress: Callable[[dict], None] | None = None,
    ray_address: str | None = None,
    **options: Any,
) -> dict:
    """`episodes` consecutive scenario seeds from `seed`; success rate (truth), mean true opening,
    median axis angle error (and, for doors, position error), seconds per episode and failure causes
    {stop_reason: count}. Episodes run in `workers` local processes, or on a Ray cluster at
    `ray_address` (see deploy/bench/executors.py)."""
    jobs = [dict(task=task, seed=s, split=split, target=target, policy=policy, **options)
            for s in range(seed, seed + episodes)]
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
    return {
        "task": task, "target": target, "split": split, "policy": policy, "episodes": episodes,
        "success_rate": float(np.mean([r["success"] for r in results])) if results else 0.0,
        "mean_opened": float(np.mean([r["true_opened"] for r in results])) if results else 0.0,
        "axis_angle_error_deg_median": float(np.median(angles)) if angles else None,
        "axis_position_error_m_median": float(np.median(positions)) if positions else None,
        "seconds_per_episode": float(np.mean([r["seconds"] for r in results])) if results else 0.0,
        "failures": dict(failures),
    }
