"""`.bag` / `.db3` RealSense recordings to frames directories (depth re-quantised to the directory's scale)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from drivers.camera.base import Frame
from drivers.camera.realsense_playback import SUFFIXES, RealSenseReplayCamera
from drivers.camera.record import record
from drivers.errors import RecordingError


def convert_recording(
    src: str | Path, out: str | Path, depth_scale: float = 0.001, progress: Callable[[Frame], None] | None = None
) -> dict:
    """Every frame of `src`, depth aligned to colour, raw (no post-processing), with the colour stream's
    intrinsics, written to the frames directory `out`. Returns {"out", "frames", "seconds", "source_depth_scale"}."""
    src = Path(src)
    if src.suffix.lower() not in SUFFIXES:
        raise RecordingError(f"cannot convert {src}: expected a RealSense .bag or .db3 recording")
    camera = RealSenseReplayCamera(src)
    camera.connect()
    source_depth_scale = camera.depth_scale
    summary = record(camera, out, depth_scale=depth_scale, progress=progress)  # disconnects the camera
    return {**summary, "source_depth_scale": source_depth_scale}
