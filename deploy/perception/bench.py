"""`deploy bench perception`: per-frame latency and mask IoU of each backend against the simulator's oracle masks.

Simulated recordings (scripted drawer and door openings) are made in a temporary directory; each backend
starts from the box around the first oracle mask (as a user would draw it) for `classical`, from its own
depth-based detection for `rgbd` (which, as in an episode, gets the frames with the arm's pixels removed by the
self-filter from the recorded joints, its mask minus them), and from detection (as on hardware) for `gdino-sam2`,
whose figures need the real weights in the local cache (a backend without them is skipped, naming each missing
model and its `hf download` command).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from deploy.errors import ModelError
from deploy.perception.config import DEFAULT_TRACKER, EDGETAM_TRACKER, PerceptionConfig
from deploy.perception.registry import needs
from deploy.perception.track_health import box_of, mask_iou
from drivers.camera.frames_dir import FramesRecording

if TYPE_CHECKING:
    from deploy.perception.self_filter import SelfFilter

BACKENDS: dict[str, tuple[str, dict]] = {
    "rgbd": ("rgbd", {}),
    "classical": ("classical", {}),
    "gdino-sam2": ("gdino-sam2", {"tracker": DEFAULT_TRACKER}),
    "gdino-sam2-small": ("gdino-sam2", {"tracker": "facebook/sam2.1-hiera-small"}),
    "gdino-edgetam": ("gdino-sam2", {"tracker": EDGETAM_TRACKER}),
}


def missing_weights(segmenter: str, config: PerceptionConfig) -> list[str]:
    """The models segmenter `segmenter` with `config` needs that are not on this machine, each as "ROLE SOURCE
    (fetch it with `hf download SOURCE`)" (a local directory: "ROLE SOURCE (no such model directory)"); empty for a
    segmenter without weights. Looks the models up only (`deploy models check` also loads them)."""
    from deploy.perception.models import fetch_command, resolve_checkpoint

    if not needs(segmenter, "weights"):
        return []
    needed = [("tracker", config.tracker)]
    if config.box is None or config.handle_prompt:  # as GdinoSam2Segmenter.from_config
        needed.insert(0, ("detector", config.detector))
    missing = []
    for role, source in needed:
        try:
            resolve_checkpoint(source)
        except ModelError:
            local = Path(source).expanduser().is_absolute() or source.startswith(".") or source.count("/") != 1
            fix = "no such model directory" if local else f"fetch it with `{fetch_command(source)}`"
            missing.append(f"{role} {source} ({fix})")
    return missing


def _run(name: str, overrides: dict, recordings: list[Path]) -> dict:
    """Latencies and IoUs of one backend over the recordings. The segmenter sees what it would in an episode: colour,
    depth and a calibrated camera pose (off by CALIBRATION_ERROR), the arm's pixels removed by the self-filter, no
    simulator label; the recorded oracle mask only scores it (and gives the classical backend its first box)."""
    from deploy.perception.registry import make_segmenter

    start_ms, track_ms, ious, frames = [], [], [], 0
    self_filter, open_width_m = _self_filter()
    for k, path in enumerate(recordings):
        recording = FramesRecording(path)
        first = recording.frame(0)
        box = box_of(first.mask) if needs(name, "box") else None
        segmenter = make_segmenter(name, PerceptionConfig(box=box, **overrides))
        error = _calibration_error(first.T_base_camera, np.random.default_rng(k))
        for i in range(len(recording)):
            frame = recording.frame(i)
            sensed = replace(frame, mask=None, segmentation=None,
                             T_base_camera=None if frame.T_base_camera is None else error @ frame.T_base_camera)
            record = recording.records[i]
            width_m = 0.0 if record.get("grasped") else open_width_m  # closed on the handle, else open
            seen, robot = self_filter.apply(sensed, np.asarray(record["joint_positions"]), width_m)
            clock = time.perf_counter()
            mask = segmenter.start(seen) if i == 0 else segmenter.track(seen)
            (start_ms if i == 0 else track_ms).append((time.perf_counter() - clock) * 1e3)
            ious.append(mask_iou(mask & ~robot, frame.mask))
            frames += 1
    return {
        "latency_ms_median": round(float(np.median(track_ms)), 2),
        "latency_ms_p90": round(float(np.percentile(track_ms, 90)), 2),
        "start_ms_median": round(float(np.median(start_ms)), 2),
        "iou_median": round(float(np.median(ious)), 4),
        "iou_min": round(float(np.min(ious)), 4),
        "frames": frames,
    }


def _calibration_error(T_true: np.ndarray | None, rng: np.random.Generator) -> np.ndarray:
    """The transform that turns the recording's true camera pose into what a field-grade calibration reports."""
    from deploy.config import CALIBRATION_ERROR
    from deploy.rig import simulated_calibration

    if T_true is None:
        return np.eye(4)
    return simulated_calibration(T_true, *CALIBRATION_ERROR, rng) @ np.linalg.inv(T_true)


def _self_filter() -> tuple[SelfFilter, float]:
    """The self-filter of the recordings' robot (the simulator's Panda) and its gripper's open width (m)."""
    from deploy.perception.self_filter import SelfFilter
    from drivers.arm.body import RobotBody
    from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config

    robot = load_robot_config(PANDA_SIM_CONFIG)
    return SelfFilter(RobotBody.from_robot(robot)), robot.gripper.max_width_m if robot.gripper else 0.0


def bench_perception(seeds: int = 1, fps: float = 10.0, backends: list[str] | None = None,
                     progress: Callable[[str], None] | None = None, world: str = "kitchen") -> dict:
    """{"device", "world", "backends": {NAME: {"latency_ms_median", "iou_median", "frames", ...} or {"skipped":
    why}}, "skipped_recordings": [why, ...]}.

    Recordings: a drawer and a door per seed (seeds 0 .. seeds-1) in `world`, `fps` frames per second; one whose
    scripted grasp fails (a handle the hand cannot close on) is left out with its reason.
    """
    from deploy.perception.device import choose_device
    from drivers.errors import ArmError
    from sim_fallback.scripted import record_scripted

    device, _ = choose_device("auto")
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="axisloop-bench-perception-") as tmp:
        recordings, skipped = [], []
        for seed in range(seeds):
            for task in ("drawer", "door"):
                if progress:
                    progress(f"recording {task} seed {seed}")
                path = Path(tmp) / f"{task}{seed}"
                try:
                    record_scripted(task, seed, path, fps=fps, world=world)
                except ArmError as exc:
                    skipped.append(f"{task} seed {seed}: {exc}")
                    continue
                recordings.append(path)
        if not recordings:
            raise ArmError(f"bench perception: no scripted recording could be made in the {world} world: "
                           f"{'; '.join(skipped)}; give more --seeds")
        for label in backends or list(BACKENDS):
            name, overrides = BACKENDS[label]
            if progress:
                progress(f"running {label}")
            if missing := missing_weights(name, PerceptionConfig(**overrides)):
                results[label] = {"latency_ms_median": None, "iou_median": None, "frames": 0,
                                  "skipped": f"weights not on this machine: {', '.join(missing)}"}
                continue
            try:
                results[label] = _run(name, overrides, recordings)
            except ModelError as e:
                results[label] = {"latency_ms_median": None, "iou_median": None, "frames": 0, "skipped": str(e)}
    return {"device": device, "world": world, "recordings": len(recordings), "fps": fps, "backends": results,
            "skipped_recordings": skipped}
