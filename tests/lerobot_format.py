"""The LeRobot dataset format v3.0 checked by its own rules (the `lerobot` package pins another torch than ours, so
its dataset class cannot be installed here): what `LeRobotDataset` loads and checks, written out.

- meta/info.json: codebase_version "v3.0", an integer fps, the default features (timestamp, frame_index,
  episode_index, index, task_index) as `create_empty_dataset_info` declares them, no "/" in a feature name,
  totals, splits, the data and video path templates;
- meta/tasks.parquet: indexed by the task text (pandas index metadata), task_index 0..T-1;
- meta/episodes/chunk-*/file-*.parquet: the columns `load_episodes` and the video decoder read, contiguous
  episodes whose dataset_from/to_index and video spans match their lengths;
- data/: one column per non-video feature of its dtype and shape, index 0..N-1, frame_index per episode,
  timestamps at frame_index / fps within 1e-4 s (`check_timestamps_sync`'s tolerance);
- meta/stats.json: min, max, mean, std, count per feature (images per channel), numbers matching the data;
- videos/: one file per video key that decodes to the episode's frames at fps, of the feature's shape.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

DEFAULT_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64", "index": "int64",
                    "task_index": "int64"}
EPISODE_COLUMNS = {"episode_index", "tasks", "length", "data/chunk_index", "data/file_index", "dataset_from_index",
                   "dataset_to_index", "meta/episodes/chunk_index", "meta/episodes/file_index"}
VIDEO_COLUMNS = ("chunk_index", "file_index", "from_timestamp", "to_timestamp")
STATS = ("min", "max", "mean", "std", "count")
TIMESTAMP_TOLERANCE_S = 1e-4


def check_dataset(root: Path) -> dict:
    """AssertionError naming the broken rule; else {"info", "data" (pyarrow table), "videos" (key -> frames RGB)}."""
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    fps = info["fps"]
    assert isinstance(fps, int) and fps > 0
    features = info["features"]
    assert not [name for name in features if "/" in name]
    for name, dtype in DEFAULT_FEATURES.items():
        assert features[name]["dtype"] == dtype and features[name]["shape"] == [1], name
    videos = [name for name, ft in features.items() if ft["dtype"] == "video"]
    for key in ("{chunk_index", "{file_index"):
        assert key in info["data_path"] and key in info["video_path"]
    assert "{video_key}" in info["video_path"]
    assert info["splits"] == {"train": f"0:{info['total_episodes']}"}

    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]
    task_texts = tasks.column("task").to_pylist()
    assert tasks.column("task_index").to_pylist() == list(range(len(task_texts))) == list(range(info["total_tasks"]))

    episodes = pa.concat_tables([pq.read_table(p) for p in sorted((root / "meta" / "episodes").glob("*/*.parquet"))])
    required = EPISODE_COLUMNS | {f"videos/{v}/{c}" for v in videos for c in VIDEO_COLUMNS}
    assert required <= set(episodes.column_names), required - set(episodes.column_names)
    rows = episodes.to_pylist()
    assert [r["episode_index"] for r in rows] == list(range(info["total_episodes"]))
    start = 0
    for r in rows:
        assert r["dataset_from_index"] == start and r["dataset_to_index"] - start == r["length"]
        assert set(r["tasks"]) <= set(task_texts)
        for v in videos:
            span = (r[f"videos/{v}/to_timestamp"] - r[f"videos/{v}/from_timestamp"]) * fps
            assert round(span) == r["length"], (v, span, r["length"])
        start = r["dataset_to_index"]
    assert start == info["total_frames"]

    data = pa.concat_tables([pq.read_table(root / info["data_path"].format(chunk_index=c, file_index=f))
                             for c, f in sorted({(r["data/chunk_index"], r["data/file_index"]) for r in rows})])
    assert set(data.column_names) == {name for name in features if name not in videos}
    for name, ft in features.items():
        if name in videos:
            continue
        values = np.asarray(data.column(name).to_pylist())
        shape = tuple(ft["shape"])
        assert values.shape[1:] == (() if shape == (1,) else shape), (name, values.shape, shape)
        kind = data.schema.field(name).type
        kind = kind.value_type if pa.types.is_fixed_size_list(kind) or pa.types.is_list(kind) else kind
        assert kind == pa.from_numpy_dtype(np.dtype(ft["dtype"])), (name, kind, ft["dtype"])
    assert data.column("index").to_pylist() == list(range(info["total_frames"]))
    frame_index = np.concatenate([np.arange(r["length"]) for r in rows])
    assert np.array_equal(data.column("frame_index").to_numpy(), frame_index)
    assert np.abs(data.column("timestamp").to_numpy() - frame_index / fps).max() <= TIMESTAMP_TOLERANCE_S

    stats = json.loads((root / "meta" / "stats.json").read_text())
    for name in features:
        assert set(STATS) <= set(stats[name]), name
        assert stats[name]["count"] == [info["total_frames"]]
        if name in videos:
            assert np.shape(stats[name]["mean"]) == (3, 1, 1)
            continue
        values = np.asarray(data.column(name).to_pylist(), float).reshape(info["total_frames"], -1)
        for stat, expected in (("min", values.min(0)), ("max", values.max(0)), ("mean", values.mean(0)),
                               ("std", values.std(0))):
            assert np.allclose(stats[name][stat], expected, atol=1e-5), (name, stat)

    decoded = {}
    for v in videos:
        height, width, _ = features[v]["shape"]
        capture = cv2.VideoCapture(str(root / info["video_path"].format(video_key=v, chunk_index=0, file_index=0)))
        assert round(capture.get(cv2.CAP_PROP_FPS)) == fps
        frames = []
        while True:
            ok, image = capture.read()
            if not ok:
                break
            assert image.shape == (height, width, 3)
            frames.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
        assert len(frames) == info["total_frames"], (len(frames), info["total_frames"])
        decoded[v] = frames
    return {"info": info, "data": data, "videos": decoded}
