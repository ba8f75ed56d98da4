"""The classical segmenter (no weights) on synthetic frames and on a PyBullet recording, `deploy track` with it,
and `deploy bench perception`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from deploy.cli import main
from deploy.errors import PerceptionError
from deploy.perception.bench import bench_perception
from deploy.perception.classical import fill_holes, keep_touching
from deploy.perception.config import PerceptionConfig
from deploy.perception.registry import make_segmenter
from deploy.perception.track_health import box_of, mask_iou
from deploy.synthetic import synthetic_sequence
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording


@pytest.fixture(scope="session")
def sim_recording(tmp_path_factory):
    """A scripted PyBullet drawer opening at 2 fps (14 frames, with oracle masks)."""
    from sim_fallback.scripted import record_scripted

    path = tmp_path_factory.mktemp("perception-sim") / "drawer"
    record_scripted("drawer", 0, path, fps=2.0, world="box")
    return path


def _run(segmenter, frames) -> list[float]:
    ious = [mask_iou(segmenter.start(frames[0]), frames[0].mask)]
    ious += [mask_iou(segmenter.track(f), f.mask) for f in frames[1:]]
    return ious


@pytest.mark.parametrize("kind", ["drawer", "door"])
def test_classical_on_synthetic_openings(kind):
    seq = synthetic_sequence(kind, np.random.default_rng(1), 0.25 if kind == "drawer" else 0.6, 12,
                             intrinsics=Intrinsics(320, 240, 307.5, 307.5, 159.5, 119.5))
    frames = seq.frames
    segmenter = make_segmenter("classical", PerceptionConfig(box=box_of(frames[0].mask)))
    ious = _run(segmenter, frames)
    assert min(ious) >= 0.9, ious


def test_classical_on_sim_recording_reaches_target_iou(sim_recording):
    recording = FramesRecording(sim_recording)
    frames = [recording.frame(i) for i in range(len(recording))]
    segmenter = make_segmenter("classical", PerceptionConfig(box=box_of(frames[0].mask)))
    ious = _run(segmenter, frames)
    assert np.median(ious) >= 0.9 and min(ious) >= 0.8, ious


def test_classical_needs_a_box_inside_the_image():
    with pytest.raises(PerceptionError, match="needs the object's box .*--box X0 Y0 X1 Y1"):
        make_segmenter("classical")
    intr = Intrinsics.from_fov(64, 48, 60.0)
    frame = Frame(0, 0.0, np.zeros((48, 64, 3), np.uint8), np.ones((48, 64), np.float32), intr)
    with pytest.raises(PerceptionError, match="empty or outside the 64x48 image"):
        make_segmenter("classical", PerceptionConfig(box=(100, 100, 200, 200))).start(frame)


def test_vanished_object_stops_with_one_clear_error():
    seq = synthetic_sequence("drawer", np.random.default_rng(2), 0.1, 3,
                             intrinsics=Intrinsics(320, 240, 307.5, 307.5, 159.5, 119.5))
    first = seq.frames[0]
    segmenter = make_segmenter("classical", PerceptionConfig(box=box_of(first.mask), max_redetections=1))
    segmenter.start(first)
    empty = Frame(1, 0.1, np.full_like(first.color, 255), np.zeros_like(first.depth_m), first.intrinsics)
    with pytest.raises(PerceptionError, match="lost the object at frame 1: mask area 0 px .*stopped after 1"):
        segmenter.track(empty)


def test_region_helpers():
    ring = np.zeros((7, 7), bool)
    ring[1:6, 1:6] = True
    ring[2:5, 2:5] = False
    filled = fill_holes(ring)
    assert filled[1:6, 1:6].all() and not filled[0].any()
    open_ring = ring.copy()
    open_ring[3, 5] = False  # a gap to the outside: nothing is enclosed
    assert not fill_holes(open_ring)[3, 3]
    two = np.zeros((5, 9), bool)
    two[1:4, 1:3] = two[1:4, 6:8] = True
    previous = np.zeros_like(two)
    previous[2, 1] = True
    kept = keep_touching(two, previous)
    assert kept[1:4, 1:3].all() and not kept[:, 5:].any()


def test_track_cli_with_classical(sim_recording, tmp_path, capsys):
    box = box_of(FramesRecording(sim_recording).frame(0).mask)
    out = tmp_path / "classical"
    args = ["track", str(sim_recording), "--segmenter", "classical", "--box", *map(str, box)]
    assert main([*args, "--out", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["frames"] == 14 and data["iou_vs_recorded_median"] >= 0.9
    tracked = FramesRecording(out)
    assert tracked.has_masks and len(tracked) == 14 and (out / "overlay.png").exists()
    assert tracked.records[5]["ee_pose"] == FramesRecording(sim_recording).records[5]["ee_pose"]
    assert main(args) == 2  # in place, but the recording already has masks
    assert "already has a mask/ folder: pass --out DIR" in " ".join(capsys.readouterr().err.split())
    assert main(["track", str(sim_recording), "--segmenter", "classical", "--out", str(tmp_path / "x")]) == 2
    assert "needs the object's box" in " ".join(capsys.readouterr().err.split())


def test_track_cli_writes_into_a_recording_without_masks(sim_recording, tmp_path):
    import shutil

    copy = shutil.copytree(sim_recording, tmp_path / "nomask")
    shutil.rmtree(copy / "mask")
    box = box_of(FramesRecording(sim_recording).frame(0).mask)
    assert main(["track", str(copy), "--segmenter", "classical", "--box", *map(str, box)]) == 0
    assert FramesRecording(copy).has_masks and (copy / "overlay.png").exists()


def test_track_out_the_recording_read_says_so_not_pass_out(sim_recording, capsys):
    """`track REC --out REC [--overwrite]` on a recording with masks: --out was given, and it is the recording
    being read; before: "already has a mask/ folder: pass --out DIR"."""
    from cli_run import one_line

    box = box_of(FramesRecording(sim_recording).frame(0).mask)
    args = ["track", str(sim_recording), "--segmenter", "classical", "--box", *map(str, box), "--out",
            str(sim_recording)]
    for extra in ([], ["--overwrite"]):
        assert main([*args, *extra]) == 2
        assert one_line(capsys.readouterr().err) == (
            f"error: --out {sim_recording} is the recording being read, which already has a mask/ folder: give "
            "--out another folder to write a copy with the new masks (the recorded masks are kept for comparison)")
    assert main(["track", str(sim_recording), "--out", str(sim_recording)]) == 2  # before any model loads
    assert "is the recording being read" in one_line(capsys.readouterr().err)
    assert FramesRecording(sim_recording).has_masks and len(FramesRecording(sim_recording)) == 14


def test_bench_perception_reports_every_backend():
    data = bench_perception(seeds=1, fps=2.0, backends=["classical", "gdino-sam2"], world="box")
    assert data["device"] in ("cpu", "cuda", "mps") and data["recordings"] == 2
    classical = data["backends"]["classical"]
    assert classical["frames"] > 20 and classical["iou_median"] >= 0.9 and classical["latency_ms_median"] > 0
    model = data["backends"]["gdino-sam2"]
    assert set(model) >= {"latency_ms_median", "iou_median", "frames"}
    if "skipped" in model:  # no real weights on this machine: says how to fetch them
        assert "hf download" in model["skipped"] and model["frames"] == 0


def test_a_box_over_the_whole_image_still_segments(sim_recording):
    """GrabCut learns the background outside the box: a box that leaves none is inset, not an OpenCV error."""
    frame = FramesRecording(sim_recording).frame(0)
    h, w = frame.depth_m.shape
    mask = make_segmenter("classical", PerceptionConfig(box=(-50, -50, w + 50, h + 50))).start(frame)
    assert 0 < np.count_nonzero(mask) < h * w
