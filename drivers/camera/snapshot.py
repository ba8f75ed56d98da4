"""One aligned colour/depth pair saved for inspection: colour, 16-bit depth, coloured depth and intrinsics."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from drivers.camera.base import Frame
from drivers.camera.frames_dir import depth_units
from drivers.errors import RecordingError


def colorize_depth(depth_m: np.ndarray) -> np.ndarray:
    """BGR image of a depth map: near red to far blue (turbo) over the valid range, black where invalid."""
    valid = depth_m > 0
    if not valid.any():
        return np.zeros((*depth_m.shape, 3), np.uint8)
    lo, hi = np.percentile(depth_m[valid], [1, 99])
    scaled = np.clip((depth_m - lo) / max(hi - lo, 1e-6), 0, 1)
    image = cv2.applyColorMap((255 - 255 * scaled).astype(np.uint8), cv2.COLORMAP_TURBO)
    image[~valid] = 0
    return image


def save_snapshot(frame: Frame, out: str | Path, depth_scale: float = 0.001) -> list[Path]:
    """Write color.png (RGB), depth.png (16-bit, units of `depth_scale` m), depth_color.png and
    intrinsics.json (intrinsics, depth_scale, t) into the directory `out`; returns the files."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RecordingError(f"cannot write a snapshot to {out}: it is a file; choose a directory")
    out.mkdir(parents=True, exist_ok=True)
    units, _ = depth_units(frame.depth_m, depth_scale)  # beyond 16 bits: no depth, never a wrong one
    files = {
        "color.png": cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR),
        "depth.png": units,
        "depth_color.png": colorize_depth(frame.depth_m),
    }
    for name, image in files.items():
        if not cv2.imwrite(str(out / name), image):
            raise RecordingError(f"could not write {out / name}; check the directory is writable")
    meta = {"intrinsics": frame.intrinsics.to_dict(), "depth_scale": depth_scale, "t": frame.t}
    (out / "intrinsics.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    return [out / name for name in (*files, "intrinsics.json")]
