"""One PNG of a simulated scene: colour, depth (colour-mapped) and segmentation side by side."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from drivers.camera.base import SegLabel
from drivers.errors import RecordingError
from sim_fallback.cabinet_urdf import Kind, Split
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.scenario import Scenario
from sim_fallback.scenes import scene_scenario
from sim_fallback.world import SimWorld

SEG_COLOURS_RGB = {SegLabel.BACKGROUND: (40, 40, 40), SegLabel.OBJECT: (70, 130, 230),
                   SegLabel.HANDLE: (250, 200, 40), SegLabel.ROBOT: (230, 80, 80)}


def render_scene_png(
    task: Kind | None,
    seed: int,
    out_path: str | Path,
    split: Split = "train",
    resolution: tuple[int, int] = (640, 480),
    world: str = "kitchen",
    part: str | None = None,
    assets: Path | None = None,
    object_id: str | None = None,
    scale: str = "real",
) -> tuple[Path, Scenario | KitchenScenario]:
    """Render the first camera frame (D415 noise on) of scenario `seed` of `world` ("kitchen", or "box": one cabinet
    in empty space) with `part` its target part as a user names it, in a kitchen the PartNet-Mobility object
    `object_id` of `assets` at `scale` when given (sim_fallback.scenes; task None: the object's), and write the
    three panels to `out_path`; the path and the scenario."""
    out = Path(out_path)
    if out.suffix.lower() != ".png":
        raise ValueError(f"scene image {out}: the file name must end in .png")
    scenario = scene_scenario(world, task, seed, split, part, assets, object_id, scale)
    with SimWorld(scenario) as sim:
        frame = SimCamera(sim, intrinsics=d415_intrinsics(*resolution), seed=seed, labels=True).read()
    depth = frame.depth_m
    valid = depth > 0
    lo, hi = (np.percentile(depth[valid], [1, 99]) if valid.any() else (0.0, 1.0))
    scaled = np.clip((depth - lo) / max(hi - lo, 1e-6), 0.0, 1.0)
    depth_bgr = cv2.applyColorMap((255 * (1 - scaled)).astype(np.uint8), cv2.COLORMAP_TURBO)
    depth_bgr[~valid] = 0
    seg_rgb = np.zeros_like(frame.color)
    for label, rgb in SEG_COLOURS_RGB.items():
        seg_rgb[frame.segmentation == label] = rgb
    panel = np.hstack([frame.color[:, :, ::-1], depth_bgr, seg_rgb[:, :, ::-1]])
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), panel):
        raise RecordingError(f"could not write {out}: check that the directory is writable and ends in .png")
    return out, scenario
