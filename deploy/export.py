"""`deploy export`: a frames-directory recording (or a run folder's) in the layouts other tools load.

- `tum`: the TUM RGB-D benchmark layout: `rgb/T.png` (8-bit RGB), `depth/T.png` (16-bit, 5000 units per
  metre), `rgb.txt` and `depth.txt` (`timestamp filename`, seconds since the recording started),
  `associations.txt` (colour and depth of one frame on one line), `groundtruth.txt` (`timestamp tx ty tz qx qy
  qz qw`, the camera pose in the robot base frame) when the recording has T_base_camera, `tool.txt` (the
  gripper's poses, same format; `deploy axis fit-trajectory` reads it) when it has ee_pose: the held handle's
  path, so only the frames marked `grasped` when the recording marks any (the approach is not the part's path),
  and `camera_intrinsic.json` (Open3D's pinhole JSON: the benchmark leaves intrinsics to its web page).
- `open3d`: the layout of Open3D's reconstruction system, written with `open3d.io`: `color/NNNNNN.png`,
  `depth/NNNNNN.png` (mm), `camera_intrinsic.json` (`write_pinhole_camera_intrinsic`), `config.json` pointing at
  them, `trajectory.log` (camera poses, `write_pinhole_camera_trajectory`) with T_base_camera, `object/NNNNNN.ply`
  (the masked object's cloud in 1 cm voxels, base frame where the pose is known, `write_point_cloud`) with masks,
  and `timestamps.txt` (`index t`: the layout has no times of its own).
- `rrd`: a rerun recording (extra `axisloop[viewer]`, deploy/export_rrd.py).
- `lerobot`: a LeRobot dataset, format v3.0 (deploy/export_lerobot.py).
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
from deploy.export_lerobot import VIDEO_KEY
from deploy.geometry.cloud import depth_to_points
from deploy.output_folder import PNGS, Layout, check_apart, stranger
from drivers.camera.base import Frame
from drivers.camera.frames_dir import FramesRecording, depth_units

Format = Literal["tum", "open3d", "rrd", "lerobot"]
TUM_DEPTH_PER_M = 5000.0  # the TUM RGB-D benchmark's depth PNG scale
OPEN3D_DEPTH_PER_M = 1000.0
OBJECT_VOXEL_M = 0.01  # the open3d export's object clouds: one point per 1 cm voxel (a few hundred kB a frame)
Progress = Callable[[float, float], None]
RUN_CONFIG = "config.json"  # beside a run folder's recording: the run config (deploy/report/run_folder.py)


RRD_MAGIC = b"RRF2"  # how a rerun file starts: only such a file is an earlier rrd export

# what an earlier export of ours holds, and the file that marks it
LAYOUTS: dict[str, tuple[Layout, str]] = {
    "tum": ({"rgb": PNGS, "depth": PNGS, "rgb.txt": None, "depth.txt": None, "associations.txt": None,
             "groundtruth.txt": None, "tool.txt": None, "camera_intrinsic.json": None}, "rgb.txt"),
    "open3d": ({"color": PNGS, "depth": PNGS, "object": "*.ply", "camera_intrinsic.json": None,
                "config.json": None, "trajectory.log": None, "timestamps.txt": None}, "camera_intrinsic.json"),
    "lerobot": ({"meta": {"info.json": None, "stats.json": None, "tasks.parquet": None,
                          "episodes": {"chunk-000": "*.parquet"}},
                 "data": {"chunk-000": "*.parquet"}, "videos": {VIDEO_KEY: {"chunk-000": "*.mp4"}}}, "meta/info.json"),
}


def export_recording(recording: Path, out: Path, fmt: Format, progress: Progress | None = None,
                     overwrite: bool = False, robot: str | None = None, fps: int | None = None) -> dict:
    """Write the frames recording at `recording` (or a run folder's) to `out` in layout `fmt`; a summary
    {"format", "out", "frames", "files", "depth_out_of_range_px"} (files: the index files written, relative to
    `out`; depth_out_of_range_px: depth beyond the format's 16-bit range, written as 0, no depth; None for rrd and
    lerobot, which keep no depth units). `robot` (rrd): the robot config whose URDF shows the joints, instead of
    the recording's; `fps` (lerobot): the dataset's frame rate (default: the recording's). An earlier export at
    `out` is replaced only with `overwrite`; anything else there is refused. The export is written to a hidden
    sibling of `out` and moved into place when complete: a failed one leaves nothing."""
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
            from deploy.export_rrd import write_rrd

            files = write_rrd(rec, work / out.name, progress, robot)
            _replace(out, work / out.name)
        elif fmt == "lerobot":
            from deploy.export_lerobot import write_lerobot

            files = write_lerobot(rec, work, progress, fps, _task(rec), rec.robot)
            _replace(out, work)
        else:
            files = {"tum": _tum, "open3d": partial(_open3d, final=out)}[fmt](rec, work, progress, beyond)
            _replace(out, work)
    finally:
        if work.exists():
            shutil.rmtree(work)
    return {"format": fmt, "out": str(out), "frames": len(rec), "files": files,
            "depth_out_of_range_px": beyond[0] if fmt in ("tum", "open3d") else None}


def _task(rec: FramesRecording) -> str:
    """The dataset's task text: what a run folder's config says it opened, else the generic one."""
    try:
        task = json.loads((rec.path.parent / RUN_CONFIG).read_text(encoding="utf-8"))["opening"]["task"]
    except (OSError, ValueError, KeyError, TypeError):
        task = None
    return f"open the {task}" if task in ("drawer", "door") else "open the articulated object"


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
    import open3d as o3d

    _o3d_write(o3d.io.write_pinhole_camera_intrinsic, out / "camera_intrinsic.json", _o3d_intrinsic(rec))
    return [*files, "camera_intrinsic.json"]


def _open3d(rec: FramesRecording, out: Path, progress: Progress | None, beyond: list[int], final: Path) -> list[str]:
    """Write the export to `out` with open3d.io, naming the files by where it ends up, `final`."""
    import open3d as o3d

    for sub in ("color", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    intrinsic = _o3d_intrinsic(rec)
    trajectory, times, clouds = o3d.camera.PinholeCameraTrajectory(), [], 0
    for i, frame in _frames(rec, progress):
        _o3d_write(o3d.io.write_image, out / "color" / f"{i:06d}.png", o3d.geometry.Image(np.ascontiguousarray(
            frame.color)))
        units, n = depth_units(frame.depth_m, 1.0 / OPEN3D_DEPTH_PER_M)
        beyond[0] += n
        _o3d_write(o3d.io.write_image, out / "depth" / f"{i:06d}.png", o3d.geometry.Image(units))
        times.append(f"{i} {frame.t:.6f}")
        if frame.T_base_camera is not None:
            parameters = o3d.camera.PinholeCameraParameters()
            parameters.intrinsic, parameters.extrinsic = intrinsic, np.linalg.inv(frame.T_base_camera)
            trajectory.parameters = [*trajectory.parameters, parameters]
        if frame.mask is not None:
            (out / "object").mkdir(exist_ok=True)
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(depth_to_points(
                frame.depth_m, frame.intrinsics.K, mask=frame.mask, T_base_camera=frame.T_base_camera)))
            cloud = cloud.voxel_down_sample(OBJECT_VOXEL_M)
            _o3d_write(o3d.io.write_point_cloud, out / "object" / f"{i:06d}.ply", cloud)
            clouds += 1
    _o3d_write(o3d.io.write_pinhole_camera_intrinsic, out / "camera_intrinsic.json", intrinsic)
    (out / "config.json").write_text(json.dumps({
        "name": rec.path.name, "path_dataset": str(final.resolve()),
        "path_intrinsic": str((final / "camera_intrinsic.json").resolve()),
        "depth_scale": OPEN3D_DEPTH_PER_M, "depth_max": 3.0,
    }, indent=2) + "\n", encoding="utf-8")
    (out / "timestamps.txt").write_text("# index t (s)\n" + "\n".join(times) + "\n", encoding="utf-8")
    files = ["camera_intrinsic.json", "config.json", "timestamps.txt"]
    if trajectory.parameters:
        _o3d_write(o3d.io.write_pinhole_camera_trajectory, out / "trajectory.log", trajectory)
        files.append("trajectory.log")
    return files + ([f"object/ ({clouds} clouds)"] if clouds else [])


def _o3d_intrinsic(rec: FramesRecording):
    import open3d as o3d

    intr = rec.intrinsics
    return o3d.camera.PinholeCameraIntrinsic(intr.width, intr.height, intr.fx, intr.fy, intr.cx, intr.cy)


def _o3d_write(write: Callable, path: Path, item) -> None:
    """An open3d.io writer; RecordingError naming the file when it fails."""
    if not write(str(path), item):
        raise RecordingError(f"could not write {path}: check the disk space and permissions")
