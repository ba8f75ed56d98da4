"""`deploy bench perception`: per-frame latency and mask IoU of each backend against the simulator's oracle masks.

Simulated recordings (scripted drawer and door openings) are made in a temporary directory; each backend
starts from the box around the first oracle mask (as a user would draw it) for `classical`, and from
detection (as on hardware) for `gdino-sam2`, whose figures need the real weights in the local cache.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from deploy.errors import ModelError
from deploy.perception.config import DEFAULT_TRACKER, EDGETAM_TRACKER, PerceptionConfig
from deploy.perception.track_health import box_of, mask_iou
from drivers.camera.frames_dir import FramesRecording

BACKENDS: dict[str, tuple[str, dict]] = {
    "classical": ("classical", {}),
    "gdino-sam2": ("gdino-sam2", {"tracker": DEFAULT_TRACKER}),
    "gdino-sam2-small": ("gdino-sam2", {"tracker": "facebook/sam2.1-hiera-small"}),
    "gdino-edgetam": ("gdino-sam2", {"tracker": EDGETAM_TRACKER}),
}


def _run(name: str, overrides: dict, recordings: list[Path]) -> dict:
    """Latencies and IoUs of one backend over the recordings."""
    from deploy.perception.registry import make_segmenter

    start_ms, track_ms, ious, frames = [], [], [], 0
    for path in recordings:
        recording = FramesRecording(path)
        first = recording.frame(0)
        box = box_of(first.mask) if name == "classical" else None
        segmenter = make_segmenter(name, PerceptionConfig(box=box, **overrides))
        for i in range(len(recording)):
            frame = recording.frame(i)
            clock = time.perf_counter()
            mask = segmenter.start(frame) if i == 0 else segmenter.track(frame)
            (start_ms if i == 0 else track_ms).append((time.perf_counter() - clock) * 1e3)
            ious.append(mask_iou(mask, frame.mask))
            frames += 1
    return {
        "latency_ms_median": round(float(np.median(track_ms)), 2),
        "latency_ms_p90": round(float(np.percentile(track_ms, 90)), 2),
        "start_ms_median": round(float(np.median(start_ms)), 2),
        "iou_median": round(float(np.median(ious)), 4),
        "iou_min": round(float(np.min(ious)), 4),
        "frames": frames,
    }


def bench_perception(seeds: int = 1, fps: float = 10.0, backends: list[str] | None = None,
                     progress: Callable[[str], None] | None = None) -> dict:
    """{"device", "backends": {NAME: {"latency_ms_median", "iou_median", "frames", ...} or {"skipped": why}}}.

    Recordings: a drawer and a door per seed (seeds 0 .. seeds-1), `fps` frames per second.
    """
    from deploy.perception.device import choose_device
    from sim_fallback.scripted import record_scripted

    device, _ = choose_device("auto")
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="axisloop-bench-perception-") as tmp:
        recordings = []
        for seed in range(seeds):
            for task in ("drawer", "door"):
                if progress:
                    progress(f"recording {task} seed {seed}")
                path = Path(tmp) / f"{task}{seed}"
                record_scripted(task, seed, path, fps=fps)
                recordings.append(path)
        for label in backends or list(BACKENDS):
            name, overrides = BACKENDS[label]
            if progress:
                progress(f"running {label}")
            try:
                results[label] = _run(name, overrides, recordings)
            except ModelError as e:
                results[label] = {"latency_ms_median": None, "iou_median": None, "frames": 0, "skipped": str(e)}
    return {"device": device, "recordings": len(recordings), "fps": fps, "backends": results}
