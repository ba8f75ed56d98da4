"""`deploy export --format lerobot`: a frames recording as a one-episode LeRobot dataset, format v3.0.

The layout LeRobot (0.4) reads, written with pyarrow and OpenCV (the `lerobot` package itself pins another torch):

    meta/info.json                            codebase_version "v3.0", fps, the features, path templates
    meta/stats.json                           per feature: min, max, mean, std, count (images per channel, 0..1)
    meta/tasks.parquet                        the task, indexed by its text (pandas index metadata), task_index
    meta/episodes/chunk-000/file-000.parquet  the episode: length, its rows and video span, its stats
    data/chunk-000/file-000.parquet           one row per frame: observation.state, action, observation.ee_pose,
                                              timestamp, frame_index, episode_index, index, task_index
    videos/observation.images.color/chunk-000/file-000.mp4   the colour frames (MPEG-4, yuv420p)

LeRobot needs frames at a fixed rate (its timestamps are frame_index / fps): the recording is sampled at `fps`
(default: its median frame rate), each sample taking the latest recorded frame at or before its time. State: the
joint positions and, where recorded, the gripper's opening (m); action: the commanded joints; ee_pose: the
gripper's position and quaternion (x, y, z, qx, qy, qz, qw); each only when the recording has it on every frame.
Depth is left out (LeRobot's video features are 8-bit colour).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.spatial.transform import Rotation

from deploy.errors import RecordingError
from drivers.camera.frames_dir import FramesRecording

Progress = Callable[[float, float], None]
CODEBASE_VERSION = "v3.0"
VIDEO_KEY = "observation.images.color"
DATA_FILE = "data/chunk-000/file-000.parquet"
EPISODES_FILE = "meta/episodes/chunk-000/file-000.parquet"
VIDEO_FILE = f"videos/{VIDEO_KEY}/chunk-000/file-000.mp4"
DEFAULT_FEATURES = {name: {"dtype": dtype, "shape": [1], "names": None} for name, dtype in (
    ("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"), ("index", "int64"),
    ("task_index", "int64"))}


def write_lerobot(rec: FramesRecording, out: Path, progress: Progress | None = None, fps: int | None = None,
                  task: str = "open the articulated object", robot_type: str | None = None) -> list[str]:
    """Write `rec` as a LeRobot dataset folder `out` (new); the files written, relative to `out`."""
    times = np.array([float(r["t"]) for r in rec.records])
    fps = fps or _median_rate(times)
    picks = _samples(times, fps)
    vectors = _vectors(rec, picks)
    intr = rec.intrinsics
    features = {name: {"dtype": "float32", "shape": [values.shape[1]], "names": names}
                for name, (names, values) in vectors.items()}
    features[VIDEO_KEY] = {"dtype": "video", "shape": [intr.height, intr.width, 3],
                           "names": ["height", "width", "channels"],
                           "info": {"video.height": intr.height, "video.width": intr.width, "video.codec": "mpeg4",
                                    "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": fps,
                                    "video.channels": 3, "has_audio": False}}
    features.update(DEFAULT_FEATURES)
    n = len(picks)
    columns = {name: values for name, (_, values) in vectors.items()}
    columns.update({"timestamp": (np.arange(n) / fps).astype(np.float32), "frame_index": np.arange(n),
                    "episode_index": np.zeros(n, np.int64), "index": np.arange(n), "task_index": np.zeros(n, np.int64)})
    image_stats = _write_video(rec, picks, out / VIDEO_FILE, fps, progress)
    stats = {name: _stats(np.asarray(values, np.float64).reshape(n, -1)) for name, values in columns.items()}
    stats[VIDEO_KEY] = image_stats
    _write_table(out / DATA_FILE, {name: _column(values) for name, values in columns.items()})
    _write_episode(out, n, fps, task, stats)
    _write_tasks(out / "meta" / "tasks.parquet", task)
    _write_json(out / "meta" / "stats.json", stats)
    _write_json(out / "meta" / "info.json", {
        "codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": 1, "total_frames": n,
        "total_tasks": 1, "chunks_size": 1000, "data_files_size_in_mb": 100, "video_files_size_in_mb": 500,
        "fps": fps, "splits": {"train": "0:1"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": features})
    return ["meta/info.json", "meta/stats.json", "meta/tasks.parquet", EPISODES_FILE, DATA_FILE, VIDEO_FILE]


def _median_rate(times: np.ndarray) -> int:
    """The recording's median frame rate, in whole frames per second (at least 1)."""
    return max(1, int(round(1.0 / float(np.median(np.diff(times)))))) if len(times) > 1 else 1


def _samples(times: np.ndarray, fps: int) -> np.ndarray:
    """For each sample k at times[0] + k / fps up to the last frame: the latest frame at or before it."""
    n = int(np.floor((times[-1] - times[0]) * fps + 1e-9)) + 1
    return np.searchsorted(times, times[0] + np.arange(n) / fps + 1e-9, side="right") - 1


def _vectors(rec: FramesRecording, picks: np.ndarray) -> dict[str, tuple[list[str], np.ndarray]]:
    """observation.state, action and observation.ee_pose where every frame has them: name -> (names, (n, k))."""
    records = [rec.records[i] for i in picks]

    def every(key: str) -> bool:
        return all(key in r for r in rec.records)

    out: dict[str, tuple[list[str], np.ndarray]] = {}
    if every("joint_positions"):
        q = np.array([r["joint_positions"] for r in records], np.float32)
        names = [f"joint{i + 1}" for i in range(q.shape[1])]
        if every("gripper_width_m"):
            q = np.hstack([q, np.array([[r["gripper_width_m"]] for r in records], np.float32)])
            names.append("gripper_width_m")
        out["observation.state"] = names, q
    if every("joint_commands"):
        a = np.array([r["joint_commands"] for r in records], np.float32)
        out["action"] = [f"joint{i + 1}" for i in range(a.shape[1])], a
    if every("ee_pose"):
        poses = np.array([r["ee_pose"] for r in records])
        pose = np.hstack([poses[:, :3, 3], Rotation.from_matrix(poses[:, :3, :3]).as_quat()]).astype(np.float32)
        out["observation.ee_pose"] = ["x", "y", "z", "qx", "qy", "qz", "qw"], pose
    return out


def _write_video(rec: FramesRecording, picks: np.ndarray, path: Path, fps: int, progress: Progress | None) -> dict:
    """The picked frames' colour as an MPEG-4 video; their per-channel stats (0..1), as LeRobot keeps them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    intr = rec.intrinsics
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (intr.width, intr.height))
    if not writer.isOpened():
        raise RecordingError(f"could not write {path}: OpenCV has no MPEG-4 video writer here; reinstall "
                             "opencv-python-headless")
    total, squares, low, high, count = np.zeros(3), np.zeros(3), np.ones(3), np.zeros(3), 0
    cache: dict[int, np.ndarray] = {}
    try:
        for k, i in enumerate(picks):
            if int(i) not in cache:
                cache.clear()
                cache[int(i)] = rec.frame(int(i)).color
            color = cache[int(i)]
            writer.write(cv2.cvtColor(color, cv2.COLOR_RGB2BGR))
            pixels = color.reshape(-1, 3) / 255.0
            total += pixels.mean(0)
            squares += (pixels ** 2).mean(0)
            low, high, count = np.minimum(low, pixels.min(0)), np.maximum(high, pixels.max(0)), count + 1
            if progress is not None:
                progress(k + 1, len(picks))
    finally:
        writer.release()
    mean = total / count
    std = np.sqrt(np.maximum(squares / count - mean ** 2, 0.0))
    channel = lambda v: [[[float(x)]] for x in v]  # noqa: E731  (3, 1, 1): per channel
    return {"min": channel(low), "max": channel(high), "mean": channel(mean), "std": channel(std), "count": [count]}


def _stats(values: np.ndarray) -> dict:
    return {"min": values.min(0).tolist(), "max": values.max(0).tolist(), "mean": values.mean(0).tolist(),
            "std": values.std(0).tolist(), "count": [len(values)]}


def _column(values: np.ndarray) -> pa.Array:
    """A frame-per-row column: vectors as fixed-size lists, scalars as they are."""
    values = np.asarray(values)
    if values.ndim == 1:
        return pa.array(values)
    return pa.FixedSizeListArray.from_arrays(pa.array(values.ravel()), values.shape[1])


def _write_episode(out: Path, n: int, fps: int, task: str, stats: dict) -> None:
    row = {"episode_index": pa.array([0], pa.int64()), "tasks": pa.array([[task]], pa.list_(pa.string())),
           "length": pa.array([n], pa.int64()), "data/chunk_index": pa.array([0], pa.int64()),
           "data/file_index": pa.array([0], pa.int64()), "dataset_from_index": pa.array([0], pa.int64()),
           "dataset_to_index": pa.array([n], pa.int64()),
           f"videos/{VIDEO_KEY}/chunk_index": pa.array([0], pa.int64()),
           f"videos/{VIDEO_KEY}/file_index": pa.array([0], pa.int64()),
           f"videos/{VIDEO_KEY}/from_timestamp": pa.array([0.0], pa.float64()),
           f"videos/{VIDEO_KEY}/to_timestamp": pa.array([n / fps], pa.float64()),
           "meta/episodes/chunk_index": pa.array([0], pa.int64()),
           "meta/episodes/file_index": pa.array([0], pa.int64())}
    for name, values in stats.items():
        for metric, value in values.items():
            row[f"stats/{name}/{metric}"] = pa.array([np.ravel(value).tolist()], pa.list_(pa.float64()))
    _write_table(out / EPISODES_FILE, row)


def _write_tasks(path: Path, task: str) -> None:
    """The tasks table as pandas writes a frame indexed by the task text (LeRobot reads it with pandas)."""
    pandas_meta = {"index_columns": ["task"], "column_indexes": [], "columns": [
        {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
         "metadata": None},
        {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__}, "pandas_version": "2.2.0"}
    table = pa.table({"task_index": pa.array([0], pa.int64()), "task": pa.array([task], pa.string())})
    _write_table(path, table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()}))


def _write_table(path: Path, columns: dict | pa.Table) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(columns if isinstance(columns, pa.Table) else pa.table(columns), path)


def _write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=4) + "\n", encoding="utf-8")
