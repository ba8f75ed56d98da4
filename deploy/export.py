"""`deploy export`: a frames-directory recording in the layouts other tools load.

- `tum`: the TUM RGB-D benchmark layout: `rgb/T.png` (8-bit RGB), `depth/T.png` (16-bit, 5000 units per
  metre), `rgb.txt` and `depth.txt` (`timestamp filename`, seconds since the recording started),
  `associations.txt` (colour and depth of one frame on one line), `groundtruth.txt` (`timestamp tx ty tz qx qy
  qz qw`, the camera pose in the robot base frame) when the recording has T_base_camera, and `tool.txt` (the
  gripper's poses, same format; `deploy axis fit-trajectory` reads it) when it has ee_pose: the held handle's
  path, so only the frames marked `grasped` when the recording marks any (the approach is not the part's path).
- `open3d`: the layout of Open3D's reconstruction system: `color/NNNNNN.png`, `depth/NNNNNN.png` (mm),
  `camera_intrinsic.json` (`open3d.io.read_pinhole_camera_intrinsic` reads it), `config.json` pointing at them,
  and `trajectory.log` (camera poses, `open3d.io.read_pinhole_camera_trajectory`) with T_base_camera.
- `rrd`: a rerun recording (extra `axisloop[viewer]`): the camera in 3D with colour, depth and masks, and the
  gripper's pose.
"""

from __future__ import annotations

import json
import shutil
import uuid
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from deploy.errors import RecordingError
from deploy.output_folder import PNGS, Layout, check_apart, stranger
from drivers.camera.base import Frame
from drivers.camera.frames_dir import FramesRecording, depth_units

Format = Literal["tum", "open3d", "rrd"]
TUM_DEPTH_PER_M = 5000.0  # the TUM RGB-D benchmark's depth PNG scale
OPEN3D_DEPTH_PER_M = 1000.0
Progress = Callable[[float, float], None]


RRD_MAGIC = b"RRF2"  # how a rerun file starts: only such a file is an earlier rrd export

# what an earlier export of ours holds, and the file that marks it
LAYOUTS: dict[str, tuple[Layout, str]] = {
    "tum": ({"rgb": PNGS, "depth": PNGS, "rgb.txt": None, "depth.txt": None, "associations.txt": None,
             "groundtruth.txt": None, "tool.txt": None}, "rgb.txt"),
    "open3d": ({"color": PNGS, "depth": PNGS, "camera_intrinsic.json": None, "config.json": None,
                "trajectory.log": None}, "camera_intrinsic.json"),
}


def export_recording(recording: Path, out: Path, fmt: Format, progress: Progress | None = None,
                     overwrite: bool = False) -> dict:
    """Write the frames recording at `recording` to `out` in layout `fmt`; a summary {"format", "out", "frames",
    "files", "depth_out_of_range_px"} (files: the index files written, relative to `out`; depth_out_of_range_px:
    depth beyond the format's 16-bit range, written as 0, no depth; None for rrd). An earlier export at `out` is
    replaced only with `overwrite`; anything else there is refused. The export is written to a hidden sibling of
    `out` and moved into place when complete: a failed one leaves nothing."""
    out = Path(out)
    rec = FramesRecording(recording)
    if len(rec) == 0:
        raise RecordingError(f"recording {recording} has no frames: nothing to export; record again")
    check_apart(out, [recording])
    if fmt == "rrd" and out.suffix != ".rrd":
        raise RecordingError(f"export to {out}: a rerun recording is one file: give --out NAME.rrd")
    _check(out, fmt, overwrite)
    out.parent.mkdir(parents=True, exist_ok=True)
    work = out.with_name(f".{out.name}.{uuid.uuid4().hex[:8]}.partial")
    work.mkdir()
    beyond = [0]  # depth pixels beyond the format's 16-bit range, written as 0 (no depth)
    try:
        if fmt == "rrd":
            files = _rrd(rec, work / out.name, progress)
            _replace(out, work / out.name)
        else:
            files = {"tum": _tum, "open3d": partial(_open3d, final=out)}[fmt](rec, work, progress, beyond)
            _replace(out, work)
    finally:
        if work.exists():
            shutil.rmtree(work)
    return {"format": fmt, "out": str(out), "frames": len(rec), "files": files,
            "depth_out_of_range_px": None if fmt == "rrd" else beyond[0]}


def _check(out: Path, fmt: Format, overwrite: bool) -> None:
    """RecordingError unless `out` is new, an empty folder, or an export of ours and `overwrite`."""
    if not out.exists() or (fmt != "rrd" and out.is_dir() and not any(out.iterdir())):
        return
    if fmt == "rrd":
        found = None if out.is_file() and _starts_with(out, RRD_MAGIC) else out
    else:
        layout, marker = LAYOUTS[fmt]
        found = stranger(out, layout) if (out / marker).is_file() else out
    article = "a" if fmt == "tum" else "an"  # an open3d, an rrd
    if found is not None:
        held = "" if found == out else f" (it holds {found.relative_to(out)}, which deploy export does not write)"
        raise RecordingError(f"--out {out} exists and is not {article} {fmt} export{held}: refusing to write "
                             "there; choose a new path")
    if not overwrite:
        raise RecordingError(f"--out {out}: {article} {fmt} export is already there: pass --overwrite to replace it, "
                             "or choose another --out")


def _starts_with(path: Path, magic: bytes) -> bool:
    with open(path, "rb") as f:
        return f.read(len(magic)) == magic


def _replace(out: Path, new: Path) -> None:
    """Move the complete export `new` to `out`, removing what `_check` let be replaced there."""
    if out.is_dir():
        shutil.rmtree(out)
    new.replace(out)


def _frames(rec: FramesRecording, progress: Progress | None):
    for i in range(len(rec)):
        yield i, rec.frame(i)
        if progress is not None:
            progress(i + 1, len(rec))


def _png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise RecordingError(f"could not write {path}: check the disk space and permissions")


def _depth_png(path: Path, frame: Frame, per_m: float, beyond: list[int]) -> None:
    """The frame's depth as a 16-bit PNG of `per_m` units per metre; depth beyond its range is 0, no depth (never
    a wrong depth), counted in beyond[0]."""
    units, n = depth_units(frame.depth_m, 1.0 / per_m)
    beyond[0] += n
    _png(path, units)


def _tum_pose(t: float, T: np.ndarray) -> str:
    qx, qy, qz, qw = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
    x, y, z = np.asarray(T)[:3, 3]
    return f"{t:.6f} {x:.6f} {y:.6f} {z:.6f} {qx:.6f} {qy:.6f} {qz:.6f} {qw:.6f}"


def _tum(rec: FramesRecording, out: Path, progress: Progress | None, beyond: list[int]) -> list[str]:
    for sub in ("rgb", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    header = f"# file: '{rec.path.name}' (axisloop export)\n# timestamp filename\n"
    rgb, depth, pairs, camera, tool, approach = [], [], [], [], [], 0
    for i, frame in _frames(rec, progress):
        stamp = f"{frame.t:.6f}"
        _png(out / "rgb" / f"{stamp}.png", cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR))
        _depth_png(out / "depth" / f"{stamp}.png", frame, TUM_DEPTH_PER_M, beyond)
        rgb.append(f"{stamp} rgb/{stamp}.png")
        depth.append(f"{stamp} depth/{stamp}.png")
        pairs.append(f"{stamp} rgb/{stamp}.png {stamp} depth/{stamp}.png")
        if frame.T_base_camera is not None:
            camera.append(_tum_pose(frame.t, frame.T_base_camera))
        pose = rec.held_pose(i)
        if pose is not None:
            tool.append(_tum_pose(frame.t, pose))
        approach += pose is None and "ee_pose" in rec.records[i]
    files = {"rgb.txt": ("# color images\n" + header, rgb), "depth.txt": ("# depth maps\n" + header, depth),
             "associations.txt": ("", pairs)}
    if camera:
        files["groundtruth.txt"] = ("# camera pose in the robot base frame\n# timestamp tx ty tz qx qy qz qw\n",
                                    camera)
    if tool:
        held = f"# only the {len(tool)} frames marked grasped: {approach} not holding the handle left out\n" \
            if rec.marks_grasp else ""
        files["tool.txt"] = ("# gripper pose in the robot base frame (fit: deploy axis fit-trajectory tool.txt "
                             "--no-orientations)\n" + held + "# timestamp tx ty tz qx qy qz qw\n", tool)
    for name, (head, lines) in files.items():
        (out / name).write_text(head + "\n".join(lines) + "\n", encoding="utf-8")
    return list(files)


def _open3d(rec: FramesRecording, out: Path, progress: Progress | None, beyond: list[int], final: Path) -> list[str]:
    """Write the export to `out`, naming the files by where it ends up, `final`."""
    for sub in ("color", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    poses = []
    for i, frame in _frames(rec, progress):
        _png(out / "color" / f"{i:06d}.png", cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR))
        _depth_png(out / "depth" / f"{i:06d}.png", frame, OPEN3D_DEPTH_PER_M, beyond)
        if frame.T_base_camera is not None:
            poses.append(frame.T_base_camera)
    intr = rec.intrinsics
    K = intr.K
    (out / "camera_intrinsic.json").write_text(json.dumps({
        "width": intr.width, "height": intr.height,
        "intrinsic_matrix": [float(v) for v in K.T.ravel()],  # column-major, as Open3D writes it
    }, indent=2) + "\n", encoding="utf-8")
    (out / "config.json").write_text(json.dumps({
        "name": rec.path.name, "path_dataset": str(final.resolve()),
        "path_intrinsic": str((final / "camera_intrinsic.json").resolve()),
        "depth_scale": OPEN3D_DEPTH_PER_M, "depth_max": 3.0,
    }, indent=2) + "\n", encoding="utf-8")
    files = ["camera_intrinsic.json", "config.json"]
    if poses:
        blocks = [f"{i} {i} {len(poses)}\n" + "\n".join(" ".join(f"{v:.9f}" for v in row) for row in T)
                  for i, T in enumerate(poses)]
        (out / "trajectory.log").write_text("\n".join(blocks) + "\n", encoding="utf-8")
        files.append("trajectory.log")
    return files


def _rrd(rec: FramesRecording, out: Path, progress: Progress | None) -> list[str]:
    from deploy.report.viewer import RerunViewer

    viewer = RerunViewer(out, spawn=False, name=f"axisloop {rec.path.name}")
    try:
        for i, frame in _frames(rec, progress):
            pose = rec.records[i].get("ee_pose")
            viewer.frame(frame.t, frame, frame.mask, None if pose is None else np.asarray(pose))
    finally:
        viewer.close()
    return [out.name]
