"""Axis accuracy on synthetic D415-like sequences with known axes (`deploy bench axis`, `deploy axis demo`).

Two scene sets: "standard" (10 cm drawers / 20 deg doors in 11 even frames, a tripod camera above and
to one side) and "varied" (5-20 cm / 10-45 deg in 6-20 frames that start and end slowly, the camera
anywhere from head-on to 60 deg to the side and from below to above: a drawer's side wall in view, a
front seen flat, windows that cover a short stretch of the travel). Every statistic has its median, p90
and max; a failed estimate counts as 90 deg / 1 m.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from deploy.axis_pipeline import AxisPipeline
from deploy.config import Config
from deploy.geometry.estimators.registry import ESTIMATORS
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.types import Axis, JointType
from deploy.synthetic.sequence import VARIED_VIEW, SyntheticSequence, synthetic_sequence
from drivers.camera.depth_noise import DepthNoise

SCENE_SETS = ("standard", "varied")

DRAWER_TRAVEL_M = 0.10
DOOR_TRAVEL_RAD = np.radians(20.0)
GRIPPER_NOISE_M, GRIPPER_NOISE_DEG = 0.001, 0.3  # FK is sub-millimetre; the grasp itself gives a little


@dataclass(frozen=True)
class SequenceResult:
    """One estimator on one sequence: errors of the final estimate (NaN-free: None when no estimate), and
    what the estimator said of it: its confidence and direction_sigma_deg (None when not given)."""

    estimator: str
    kind: str
    angle_deg: float | None
    position_m: float | None
    joint_type_ok: bool
    ms_per_estimate: list[float]
    step_ms: list[float]
    reason: str = ""
    confidence: float | None = None
    sigma_deg: float | None = None


def with_estimator(config: Config, name: str, joint: str) -> Config:
    return config.model_copy(update={"estimator": config.estimator.model_copy(update={"name": name, "joint": joint})})


def run_sequence(seq: SyntheticSequence, name: str, config: Config) -> SequenceResult:
    """Feed every frame through the pipeline with the joint type known (as `deploy open-drawer` does),
    score the final estimate, then ask the same window for the joint type with `--joint auto`."""
    truth = seq.true_axis
    pipe = AxisPipeline(with_estimator(config, name, truth.joint_type.value))
    estimate_ms, step_ms = [], []
    step = None
    for frame, pose in zip(seq.frames, seq.gripper_poses, strict=True):
        clock = time.perf_counter()
        step = pipe.update_frame(frame, frame.mask, pose)
        if pipe.window:
            step_ms.append((time.perf_counter() - clock) * 1e3)
            estimate_ms.append(step.timings_ms["estimate"])
    auto = pipe.estimator.estimate(list(pipe.window), None)
    joint_ok = isinstance(auto, Axis) and auto.joint_type == truth.joint_type
    result = step.result if step is not None else None
    if not isinstance(result, Axis):
        reason = getattr(result, "reason", "no frames")
        return SequenceResult(name, seq.kind, None, None, joint_ok, estimate_ms, step_ms, reason)
    angle = axis_angle_error_deg(truth.direction, result.direction)
    position = None
    if truth.joint_type == JointType.REVOLUTE:
        at = seq.gripper_poses[0][:3, 3]
        position = axis_position_error_m(truth.origin, truth.direction, result.origin, result.direction, at=at)
    return SequenceResult(name, seq.kind, angle, position, joint_ok, estimate_ms, step_ms,
                          confidence=result.confidence, sigma_deg=result.direction_sigma_deg)


def make_sequences(n_per_kind: int, seed: int, noise: DepthNoise | None = None,
                   scenes: str = "standard") -> list[SyntheticSequence]:
    """`n_per_kind` drawers and doors of the scene set `scenes` (module docstring), varied sizes and poses,
    D415 noise, 1 mm noise on the gripper positions and 0.3 deg on their orientations."""
    if scenes not in SCENE_SETS:
        raise ValueError(f"unknown scene set {scenes!r}: use one of {', '.join(SCENE_SETS)}")
    noise = DepthNoise.d415() if noise is None else noise
    rng = np.random.default_rng(seed)
    grip = {"gripper_noise_m": GRIPPER_NOISE_M, "gripper_noise_deg": GRIPPER_NOISE_DEG, "noise": noise}
    seqs = []
    for _ in range(n_per_kind):
        if scenes == "standard":
            seqs.append(synthetic_sequence("drawer", rng, travel=DRAWER_TRAVEL_M, n_frames=11, **grip))
            seqs.append(synthetic_sequence("door", rng, travel=DOOR_TRAVEL_RAD, n_frames=11, **grip))
            continue
        for kind, travel in (("drawer", rng.uniform(0.05, 0.20)), ("door", np.radians(rng.uniform(10, 45)))):
            seqs.append(synthetic_sequence(kind, rng, travel=travel, n_frames=int(rng.integers(6, 21)),
                                           view=VARIED_VIEW, easing=True, **grip))
    return seqs


def _stat(values: list[float], q: float) -> float | None:
    """The q-th percentile, None for no values."""
    return None if not values else float(np.percentile(values, q))


def _errors(results: list[SequenceResult], kind: str, attr: str, fail: float) -> list[float]:
    """One error per sequence of `kind`; a failed estimate counts as `fail` so failures stay in the stats."""
    return [fail if getattr(r, attr) is None else getattr(r, attr) for r in results if r.kind == kind]


def _spread(values: list[float], name: str) -> dict[str, float | None]:
    """`name`_median, _p90 and _max of the values."""
    return {f"{name}_median": _stat(values, 50), f"{name}_p90": _stat(values, 90), f"{name}_max": _stat(values, 100)}


def _says_when_unsure(results: list[SequenceResult], kind: str) -> dict[str, float | int | None]:
    """Whether the estimator's own uncertainty tells its good estimates from its bad ones, over the
    estimates of `kind`: how many carry a direction_sigma_deg and the share of those whose angle error is
    within 2 sigma; the median angle error of the less confident half and of the more confident half
    (split at the median confidence; failures left out: they say so themselves)."""
    answered = sorted((r for r in results if r.kind == kind and r.angle_deg is not None and r.confidence is not None),
                      key=lambda r: r.confidence)
    sized = [r for r in answered if r.sigma_deg is not None]
    half = len(answered) // 2
    return {
        f"{kind}_sigma_reported": len(sized),
        f"{kind}_within_2_sigma": None if not sized
        else sum(r.angle_deg <= 2 * r.sigma_deg for r in sized) / len(sized),
        f"{kind}_angle_deg_median_low_confidence": _stat([r.angle_deg for r in answered[:half]], 50),
        f"{kind}_angle_deg_median_high_confidence": _stat([r.angle_deg for r in answered[len(answered) - half:]], 50),
    }


def coverage(results: list[SequenceResult]) -> dict[str, float | int | None]:
    """How honest the reported direction_sigma_deg is: `coverage_2_sigma`, the share of the estimates that
    report one whose angle error is within 2 sigma (about 95 % for a well-calibrated sigma; 90-99 % is the
    target), over `coverage_estimates` such estimates (drawers and doors)."""
    sized = [r for r in results if r.angle_deg is not None and r.sigma_deg is not None]
    return {"coverage_2_sigma": sum(r.angle_deg <= 2 * r.sigma_deg for r in sized) / len(sized) if sized else None,
            "coverage_estimates": len(sized)}


def summarise(results: list[SequenceResult]) -> dict:
    """Per-estimator statistics in the `deploy bench axis --json` schema: median, p90 and max of every
    error, why estimates failed (reason -> count), and whether the estimator says when it is unsure
    (`_says_when_unsure`, per kind)."""
    out: dict = {}
    for name in dict.fromkeys(r.estimator for r in results):
        mine = [r for r in results if r.estimator == name]
        failures: dict[str, int] = {}
        for r in mine:
            if r.angle_deg is None:
                failures[f"{r.kind}: {r.reason}"] = failures.get(f"{r.kind}: {r.reason}", 0) + 1
        out[name] = {
            **_spread(_errors(mine, "drawer", "angle_deg", 90.0), "drawer_angle_deg"),
            **_spread(_errors(mine, "door", "angle_deg", 90.0), "door_angle_deg"),
            **_spread(_errors(mine, "door", "position_m", 1.0), "door_position_m"),
            **_says_when_unsure(mine, "drawer"),
            **_says_when_unsure(mine, "door"),
            **coverage(mine),
            "joint_type_accuracy": float(np.mean([r.joint_type_ok for r in mine])),
            "failed_estimates": sum(r.angle_deg is None for r in mine),
            "failures": failures,
            "ms_median": _stat([m for r in mine for m in r.ms_per_estimate], 50),
            "sequences": len(mine),
        }
    return out


def bench_axis(
    n_per_kind: int = 20, seed: int = 0, estimators: tuple[str, ...] | None = None,
    config: Config | None = None, progress: Callable[[int, int], None] | None = None, scenes: str = "standard",
) -> dict:
    """Run every estimator on the same synthetic sequences of the scene set `scenes`; returns the `--json` dict."""
    config = config or Config()
    estimators = tuple(estimators or ESTIMATORS.names())
    seqs = make_sequences(n_per_kind, seed, scenes=scenes)
    results, default_steps = [], []
    total = len(seqs) * len(estimators)
    for i, seq in enumerate(seqs):
        for j, name in enumerate(estimators):
            result = run_sequence(seq, name, config)
            results.append(result)
            if name == config.estimator.name:
                default_steps += result.step_ms
            if progress:
                progress(i * len(estimators) + j + 1, total)
    return {
        "estimators": summarise(results),
        "step_ms_median": _stat(default_steps, 50),
        "step_estimator": config.estimator.name,
        "sequences": len(seqs),
        "seed": seed,
        "scenes": scenes,
    }


def demo_axis(seed: int = 0) -> list[SequenceResult]:
    """One noisy synthetic drawer and door, every estimator: the rows of `deploy axis demo`."""
    seqs = make_sequences(1, seed)
    return [run_sequence(seq, name, Config()) for seq in seqs for name in ESTIMATORS.names()]
