"""RGB-D image folders to frames directories: the TUM RGB-D benchmark's layout and Open3D's reconstruction layout,
as `deploy export` writes them and as others do (`deploy convert`, docs/recording-format.md).

TUM RGB-D: `rgb.txt` and `depth.txt` (`timestamp filename`, `#` comments), 16-bit depth PNGs of 5000 units per
metre registered to the colour images; colour and depth paired by `associations.txt` where there is one, else each
colour image with the nearest unused depth image within 20 ms (the benchmark's associate.py); camera poses from
`groundtruth.txt` (`timestamp tx ty tz qx qy qz qw`), interpolated at the colour times inside its span;
`tool.txt` (ours) gives the gripper's poses. Intrinsics from `camera_intrinsic.json` (Open3D's pinhole JSON, which
our export writes), else the benchmark's published ones for a `freiburg1/2/3` folder.

Open3D: `color/` (or `image/`, `rgb/`) and `depth/` images in name order, `camera_intrinsic.json` (or config.json's
`path_intrinsic`), config.json's `depth_scale` (units per metre, default 1000), camera poses from `trajectory.log`
(or `scene/trajectory.log`), frame times from `timestamps.txt` (ours) or 30 per second (Open3D's recorder).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import DEPTH_SCALE, FramesWriter
from drivers.errors import RecordingError

TUM_DEPTH_PER_M = 5000.0
TUM_MAX_DT_S = 0.02  # colour and depth images further apart in time are not one frame (associate.py's default)
TUM_FREIBURG = {  # the benchmark's published colour intrinsics (fx, fy, cx, cy) at 640x480
    "freiburg1": (517.3, 516.5, 318.6, 255.3), "freiburg2": (520.9, 521.0, 325.1, 249.7),
    "freiburg3": (535.4, 539.2, 320.1, 247.6)}
OPEN3D_COLOR_DIRS = ("color", "image", "rgb")
OPEN3D_FPS = 30.0  # frame times of an Open3D folder without timestamps.txt
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class FolderFrame:
    """One frame of a folder: time (s from the first), its image files, camera and gripper poses where known."""

    t: float
    color: Path
    depth: Path
    T_base_camera: np.ndarray | None = None
    ee_pose: np.ndarray | None = None


@dataclass(frozen=True)
class Folder:
    """A folder's frames, intrinsics and depth unit (m per unit), and what its summary reports."""

    kind: str
    frames: list[FolderFrame]
    intrinsics: Intrinsics
    depth_scale: float
    unpaired: dict[str, int]


def folder_kind(src: Path) -> str | None:
    """"tum" (rgb.txt and depth.txt), "open3d" (depth/ beside color/, image/ or rgb/), or None (a frames directory,
    whose meta.json sets it apart, among others)."""
    src = Path(src)
    if (src / "meta.json").is_file():
        return None
    if (src / "rgb.txt").is_file() and (src / "depth.txt").is_file():
        return "tum"
    if (src / "depth").is_dir() and any((src / name).is_dir() for name in OPEN3D_COLOR_DIRS):
        return "open3d"
    return None


def read_folder(src: Path) -> Folder:
    """The TUM or Open3D folder `src`; RecordingError naming what is missing otherwise."""
    kind = folder_kind(src)
    if kind is None:
        raise RecordingError(f"{src} is neither a TUM RGB-D folder (rgb.txt, depth.txt) nor an Open3D one (color/, "
                             "depth/): give the folder that holds them")
    return read_tum(src) if kind == "tum" else read_open3d(src)


def convert_folder(src: str | Path, out: str | Path, depth_scale: float | None = None,
                   progress: Callable[[Frame], None] | None = None) -> dict:
    """Every frame of the folder `src` to the frames directory `out` (depth re-quantised to `depth_scale` m; None:
    the folder's own unit, at most 1 mm), as `deploy convert` reports it: {"out", "frames", "seconds", "source",
    "depth_scale", "source_depth_scale", "depth_out_of_range_px", "source_frames", "unpaired_frames", "poses"}."""
    folder = read_folder(Path(src))
    depth_scale = min(folder.depth_scale, DEPTH_SCALE) if depth_scale is None else depth_scale
    poses = [f.T_base_camera for f in folder.frames]
    static = poses[0] if all(p is not None for p in poses) and all(np.allclose(p, poses[0]) for p in poses) else None
    with FramesWriter(out, folder.intrinsics, depth_scale, static, f"convert:{folder.kind}") as writer:
        for i, item in enumerate(folder.frames):
            frame = Frame(i, item.t, _color(item.color, folder.intrinsics),
                          _depth(item.depth, folder.intrinsics) * np.float32(folder.depth_scale), folder.intrinsics,
                          item.T_base_camera)
            writer.write(frame, ee_pose=item.ee_pose)
            if progress is not None:
                progress(frame)
    n = len(folder.frames)
    return {"out": str(out), "frames": n, "seconds": folder.frames[-1].t - folder.frames[0].t,
            "source": folder.kind, "depth_scale": depth_scale, "source_depth_scale": folder.depth_scale,
            "depth_out_of_range_px": writer.depth_out_of_range_px,
            "source_frames": {"color": n + folder.unpaired["color"], "depth": n + folder.unpaired["depth"]},
            "unpaired_frames": folder.unpaired, "poses": sum(p is not None for p in poses)}


# --- TUM RGB-D ---------------------------------------------------------------------------------------------


def read_tum(src: Path) -> Folder:
    rgb, depth = _stamped(src / "rgb.txt"), _stamped(src / "depth.txt")
    pairs = _associations(src) if (src / "associations.txt").is_file() else _pair(rgb, depth)
    if not pairs:
        raise RecordingError(f"{src}: no colour image has a depth image within {TUM_MAX_DT_S * 1e3:.0f} ms: check "
                             "rgb.txt and depth.txt")
    times = np.array([t for t, _, _ in pairs])
    cameras = _interpolated(_poses(src / "groundtruth.txt"), times)
    tools = _matched(_poses(src / "tool.txt"), times)
    frames = [FolderFrame(t - times[0], src / c, src / d, cam, tool)
              for (t, c, d), cam, tool in zip(pairs, cameras, tools, strict=True)]
    return Folder("tum", frames, _tum_intrinsics(src, frames[0].color), 1.0 / TUM_DEPTH_PER_M,
                  {"color": len(rgb) - len(pairs), "depth": len(depth) - len(pairs)})


def _lines(file: Path) -> list[list[str]]:
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read {file} ({exc}): restore it") from None
    return [line.split() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def _stamped(file: Path) -> list[tuple[float, str]]:
    """`timestamp filename` lines, in time order."""
    try:
        return sorted((float(parts[0]), parts[1]) for parts in _lines(file))
    except (ValueError, IndexError):
        raise RecordingError(f"{file}: each line must be `timestamp filename`: fix the line") from None


def _associations(src: Path) -> list[tuple[float, str, str]]:
    try:
        return sorted((float(p[0]), p[1], p[3]) for p in _lines(src / "associations.txt"))
    except (ValueError, IndexError):
        raise RecordingError(f"{src / 'associations.txt'}: each line must be `t rgb/FILE t depth/FILE`: fix the "
                             "line, or remove the file to pair the images by time") from None


def _pair(rgb: list[tuple[float, str]], depth: list[tuple[float, str]]) -> list[tuple[float, str, str]]:
    """Each colour image with the nearest depth image within TUM_MAX_DT_S, each used once, closest pairs first."""
    if not depth:
        return []
    d_times = np.array([t for t, _ in depth])
    candidates = sorted((abs(t - d_times[j]), i, j) for i, (t, _) in enumerate(rgb)
                        for j in np.flatnonzero(np.abs(d_times - t) <= TUM_MAX_DT_S))
    used_rgb, used_depth, pairs = set(), set(), []
    for _, i, j in candidates:
        if i not in used_rgb and j not in used_depth:
            used_rgb.add(i)
            used_depth.add(j)
            pairs.append((rgb[i][0], rgb[i][1], depth[j][1]))
    return sorted(pairs)


def _poses(file: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """`timestamp tx ty tz qx qy qz qw` lines: times (n,) and 4x4 poses (n, 4, 4); None without the file."""
    if not file.is_file():
        return None
    try:
        rows = np.array(sorted([float(v) for v in parts[:8]] for parts in _lines(file)), float)
        T = np.tile(np.eye(4), (len(rows), 1, 1))
        T[:, :3, :3] = Rotation.from_quat(rows[:, 4:8]).as_matrix()
        T[:, :3, 3] = rows[:, 1:4]
    except (ValueError, IndexError):
        raise RecordingError(f"{file}: each line must be `timestamp tx ty tz qx qy qz qw`: fix the line") from None
    return (rows[:, 0], T) if len(rows) else None


def _interpolated(poses: tuple[np.ndarray, np.ndarray] | None, times: np.ndarray) -> list[np.ndarray | None]:
    """The poses at `times` (positions linear, rotations slerped), None outside their time span."""
    if poses is None:
        return [None] * len(times)
    t, T = poses
    if len(t) == 1:
        return [T[0].copy() if abs(x - t[0]) <= TUM_MAX_DT_S else None for x in times]
    slerp = Slerp(t, Rotation.from_matrix(T[:, :3, :3]))
    out: list[np.ndarray | None] = []
    for x in times:
        if not t[0] <= x <= t[-1]:
            out.append(None)
            continue
        pose = np.eye(4)
        pose[:3, :3] = slerp([x]).as_matrix()[0]
        pose[:3, 3] = [np.interp(x, t, T[:, k, 3]) for k in range(3)]
        out.append(pose)
    return out


def _matched(poses: tuple[np.ndarray, np.ndarray] | None, times: np.ndarray) -> list[np.ndarray | None]:
    """The pose stamped at each of `times` (within 1 ms), None where there is none."""
    if poses is None:
        return [None] * len(times)
    t, T = poses
    nearest = np.abs(t[None, :] - times[:, None]).argmin(axis=1)
    return [T[j].copy() if abs(t[j] - x) <= 1e-3 else None for j, x in zip(nearest, times, strict=True)]


def _tum_intrinsics(src: Path, first_color: Path) -> Intrinsics:
    if (src / "camera_intrinsic.json").is_file():
        return _open3d_intrinsics(src / "camera_intrinsic.json")
    height, width = _color(first_color, None).shape[:2]
    for name, (fx, fy, cx, cy) in TUM_FREIBURG.items():
        if name in src.resolve().name and (width, height) == (640, 480):
            return Intrinsics(width, height, fx, fy, cx, cy)
    raise RecordingError(f"{src}: no camera_intrinsic.json and not a freiburg1/2/3 sequence of the benchmark: write "
                         "the colour camera's intrinsics there in Open3D's format ({\"width\": W, \"height\": H, "
                         "\"intrinsic_matrix\": [fx, 0, 0, 0, fy, 0, cx, cy, 1]})")


# --- Open3D ------------------------------------------------------------------------------------------------


def read_open3d(src: Path) -> Folder:
    color_dir = next(src / name for name in OPEN3D_COLOR_DIRS if (src / name).is_dir())
    colors, depths = _images(color_dir), _images(src / "depth")
    if not colors or len(colors) != len(depths):
        raise RecordingError(f"{src}: {len(colors)} colour and {len(depths)} depth images: an Open3D folder pairs "
                             "them by name order, one each; remove the extra images")
    config = _json(src / "config.json") if (src / "config.json").is_file() else {}
    intrinsic_file = Path(config.get("path_intrinsic") or src / "camera_intrinsic.json")
    if not intrinsic_file.is_file():
        raise RecordingError(f"{src}: no camera_intrinsic.json (nor config.json's path_intrinsic): write the "
                             "camera's intrinsics with open3d.io.write_pinhole_camera_intrinsic")
    times = _open3d_times(src, len(colors))
    poses = _trajectory(src, len(colors))
    frames = [FolderFrame(t, c, d, pose) for t, c, d, pose in zip(times, colors, depths, poses, strict=True)]
    return Folder("open3d", frames, _open3d_intrinsics(intrinsic_file),
                  1.0 / float(config.get("depth_scale", 1000.0)), {"color": 0, "depth": 0})


def _images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)


def _json(file: Path) -> dict:
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{file} is not valid JSON ({exc}): fix or remove it") from None
    if not isinstance(data, dict):
        raise RecordingError(f"{file} is not a JSON object: fix or remove it")
    return data


def _open3d_intrinsics(file: Path) -> Intrinsics:
    data = _json(file)
    try:
        K = np.asarray(data["intrinsic_matrix"], float).reshape(3, 3).T  # stored column-major
        return Intrinsics(int(data["width"]), int(data["height"]), K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    except (KeyError, ValueError, TypeError):
        raise RecordingError(f"{file}: expected Open3D's pinhole JSON (width, height, intrinsic_matrix of 9 values, "
                             "column-major): rewrite it with open3d.io.write_pinhole_camera_intrinsic") from None


def _open3d_times(src: Path, n: int) -> list[float]:
    if not (src / "timestamps.txt").is_file():
        return [i / OPEN3D_FPS for i in range(n)]
    try:
        times = [float(parts[1]) for parts in _lines(src / "timestamps.txt")]
    except (ValueError, IndexError):
        raise RecordingError(f"{src / 'timestamps.txt'}: each line must be `index t`: fix the line") from None
    if len(times) != n:
        raise RecordingError(f"{src / 'timestamps.txt'} lists {len(times)} times for {n} frames: fix or remove it")
    return times


def _trajectory(src: Path, n: int) -> list[np.ndarray | None]:
    """The camera poses of trajectory.log (or scene/trajectory.log) when it has one per frame."""
    import open3d as o3d

    for file in (src / "trajectory.log", src / "scene" / "trajectory.log"):
        if file.is_file():
            parameters = o3d.io.read_pinhole_camera_trajectory(str(file)).parameters
            if len(parameters) == n:
                return [np.linalg.inv(p.extrinsic) for p in parameters]
    return [None] * n


# --- images ------------------------------------------------------------------------------------------------


def _color(file: Path, intrinsics: Intrinsics | None) -> np.ndarray:
    image = cv2.imread(str(file), cv2.IMREAD_COLOR)
    if image is None:
        raise RecordingError(f"{file} is missing or not an image: restore it, or remove its line")
    if intrinsics is not None and image.shape[:2] != (intrinsics.height, intrinsics.width):
        raise RecordingError(f"{file} is {image.shape[1]}x{image.shape[0]}, the intrinsics say "
                             f"{intrinsics.width}x{intrinsics.height}: fix the intrinsics file")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _depth(file: Path, intrinsics: Intrinsics) -> np.ndarray:
    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None or image.dtype != np.uint16 or image.ndim != 2:
        raise RecordingError(f"{file} is missing or not a 16-bit depth PNG: restore it")
    if image.shape != (intrinsics.height, intrinsics.width):
        raise RecordingError(f"{file} is {image.shape[1]}x{image.shape[0]}, the colour images "
                             f"{intrinsics.width}x{intrinsics.height}: the depth must be registered to colour")
    return image.astype(np.float32)
