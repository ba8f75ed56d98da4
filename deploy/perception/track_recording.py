"""`deploy track`: run a segmenter over a frames recording, frame by frame, and write its masks and an overlay."""

from __future__ import annotations

import json
import shutil
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from deploy.errors import PerceptionError
from deploy.perception.base import Segmenter
from deploy.perception.track_health import mask_iou
from drivers.camera.base import Frame
from drivers.camera.frames_dir import FramesRecording, FramesWriter

OVERLAY_TILES = 6


def overlay(frame: Frame, mask: np.ndarray, width: int = 320) -> np.ndarray:
    """The frame's colour (RGB) with the mask tinted red and outlined, scaled to `width` pixels."""
    image = frame.color.copy()
    image[mask] = (0.5 * image[mask] + (127, 0, 0)).astype(np.uint8)
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(image, contours, -1, (255, 40, 40), 2)
    cv2.putText(image, f"{frame.index}", (8, 28), cv2.FONT_HERSHEY_SIMPLEX, 0.9, (255, 255, 0), 2)
    scale = width / image.shape[1]
    return cv2.resize(image, (width, int(round(image.shape[0] * scale))), interpolation=cv2.INTER_AREA)


def _write_mask(directory: Path, index: int, mask: np.ndarray) -> None:
    if not cv2.imwrite(str(directory / f"{index:06d}.png"), np.where(mask, 255, 0).astype(np.uint8)):
        raise PerceptionError(f"could not write {directory}/{index:06d}.png: check the disk and permissions")


def copy_target(path: Path, out: Path | None, recording: FramesRecording) -> Path | None:
    """Where `track_recording` writes a copy: `out`, or None for the recording's own mask/ folder (`out` the
    recording itself counts as none); PerceptionError when that folder is there already."""
    if out is not None and out.resolve() == Path(path).resolve():
        if recording.has_masks:
            raise PerceptionError(f"--out {out} is the recording being read, which already has a mask/ folder: "
                                  "give --out another folder to write a copy with the new masks (the recorded "
                                  "masks are kept for comparison)")
        out = None  # the masks go into the recording itself, as without --out
    if out is None and recording.has_masks:
        raise PerceptionError(f"recording {path} already has a mask/ folder: pass --out DIR to write the new "
                              "masks into a copy (the recorded masks are kept for comparison)")
    return out


def track_recording(path: Path, segmenter: Segmenter, prompt: str, out: Path | None = None,
                    progress: Callable[[float, float], None] | None = None, viewer: Any = None) -> dict:
    """Segment every frame of the recording at `path` in order (start on the first, track on the rest).

    With `out`, a copy of the recording with the new masks is written there (truth.json and the `first` and
    `grasped` marks copied too; a recording already at `out` is refused: `deploy.output_folder.new_output`
    replaces it when the user asks); without, the masks go into the recording's own mask/ folder, which must not
    exist yet: they are written to a hidden folder beside it and renamed to mask/ once every frame has one (a
    failure leaves none); `out` the recording itself counts as none. A PNG strip of a few evenly spaced frames is
    written beside. Returns a summary (timings in ms; IoU against the recording's own masks when it has them).
    progress(done, total) follows the frames; `viewer` (deploy.report.viewer.RerunViewer) is shown every frame
    with its mask and is closed at the end.
    """
    recording = FramesRecording(path)
    n = len(recording)
    if n == 0:
        raise PerceptionError(f"recording {path} has no frames: record again")
    out = copy_target(path, out, recording)
    target = out or Path(path)
    writer, masks = None, None
    if out is not None:
        writer = FramesWriter(out, recording.intrinsics, recording.depth_scale, recording.T_base_camera,
                              recording.camera, recording.simulated)
        if (Path(path) / "truth.json").exists():
            shutil.copyfile(Path(path) / "truth.json", out / "truth.json")
    else:
        masks = target / f".mask-{uuid.uuid4().hex[:8]}.partial"
        masks.mkdir()
    tiles_at = set(np.linspace(0, n - 1, min(OVERLAY_TILES, n)).round().astype(int).tolist())
    tiles, ms, ious = [], [], []
    try:
        for i in range(n):
            frame = recording.frame(i)
            clock = time.perf_counter()
            mask = segmenter.start(frame, prompt) if i == 0 else segmenter.track(frame)
            ms.append((time.perf_counter() - clock) * 1e3)
            if frame.mask is not None:
                ious.append(mask_iou(mask, frame.mask))
            if writer is not None:
                record = recording.records[i]
                pose = record.get("ee_pose")
                writer.write(frame, mask=mask, joint_positions=record.get("joint_positions"),
                             ee_pose=None if pose is None else np.asarray(pose), first=bool(record.get("first")),
                             grasped=record.get("grasped"))
            else:
                _write_mask(masks, frame.index, mask)
            if i in tiles_at:
                tiles.append(overlay(frame, mask))
            if viewer is not None:
                pose = recording.records[i].get("ee_pose")
                viewer.frame(frame.t, frame, mask, None if pose is None else np.asarray(pose))
            if progress is not None:
                progress(i + 1, n)
    except BaseException:
        if masks is not None:
            shutil.rmtree(masks)
        raise
    finally:
        if writer is not None:
            writer.close()
        if viewer is not None:
            viewer.close()
    if masks is not None:
        masks.rename(target / "mask")
    strip = target / "overlay.png"
    cv2.imwrite(str(strip), cv2.cvtColor(np.hstack(tiles), cv2.COLOR_RGB2BGR))
    summary = {
        "recording": str(path), "segmenter": segmenter.name, "prompt": prompt, "frames": n,
        "masks": str(target / "mask"), "overlay": str(strip), "start_ms": round(ms[0], 2),
        "track_ms_median": round(float(np.median(ms[1:])), 2) if n > 1 else None,
        "iou_vs_recorded_median": round(float(np.median(ious)), 4) if ious else None,
        "redetections": segmenter.redetections,
    }
    (target / "track.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary
