"""Grounding DINO + SAM2 video, end to end on the CPU, with tiny randomly initialised checkpoints saved by
save_pretrained and loaded through the same code users run (`deploy.perception.models`)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from perception_tiny_models import save_tiny_edgetam_video, save_tiny_grounding_dino, save_tiny_sam2_video

from deploy.cli import main
from deploy.errors import ModelError, PerceptionError
from deploy.perception.config import PerceptionConfig
from deploy.perception.gdino import GroundingDinoDetector
from deploy.perception.models import check_models, load_detector, load_tracker, resolve_checkpoint
from deploy.perception.registry import make_segmenter
from deploy.perception.sam2_video import StreamingTracker
from deploy.synthetic import synthetic_sequence, write_sequence
from drivers.camera.base import Intrinsics
from drivers.camera.frames_dir import FramesRecording

SMALL = Intrinsics(160, 120, 154.0, 154.0, 79.5, 59.5)
BOX = (20.0, 15.0, 130.0, 105.0)


@pytest.fixture(scope="session")
def checkpoints(tmp_path_factory):
    """(detector dir, tracker dir) of tiny random models."""
    root = tmp_path_factory.mktemp("tiny-models")
    return save_tiny_grounding_dino(root / "gdino"), save_tiny_sam2_video(root / "sam2")


@pytest.fixture(scope="session")
def sequence():
    return synthetic_sequence("drawer", np.random.default_rng(3), 0.2, 10, intrinsics=SMALL)


def _config(checkpoints, **overrides) -> PerceptionConfig:
    detector, tracker = checkpoints
    return PerceptionConfig(detector=str(detector), tracker=str(tracker), device="cpu", **overrides)


def test_detector_sorts_by_score_and_filters_by_region(checkpoints, sequence):
    detector = GroundingDinoDetector(*load_detector(str(checkpoints[0])), box_threshold=0.0, text_threshold=0.0)
    color = sequence.frames[0].color
    found = detector.detect(color, "cabinet")
    assert len(found) >= 2
    scores = [d.score for d in found]
    assert scores == sorted(scores, reverse=True) and all(0 <= s <= 1 for s in scores)
    for d in found:
        x0, y0, x1, y1 = d.box
        assert -1 <= x0 <= x1 <= SMALL.width + 1 and -1 <= y0 <= y1 <= SMALL.height + 1
    region = (0.0, 0.0, 80.0, 60.0)
    inside = detector.detect(color, "cabinet", within=region)
    assert all(0 <= (d.box[0] + d.box[2]) / 2 <= 80 and 0 <= (d.box[1] + d.box[3]) / 2 <= 60 for d in inside)
    assert len(inside) < len(found)


def test_streaming_tracker_keeps_memory_bounded(checkpoints, sequence):
    tracker = StreamingTracker(*load_tracker(str(checkpoints[1])))
    first = tracker.start(sequence.frames[0].color, {1: BOX, 2: (60.0, 40.0, 90.0, 60.0)})
    assert set(first) == {1, 2} and first[1].shape == (SMALL.height, SMALL.width) and first[1].dtype == bool
    assert first[1].any()
    frames = [f.color for f in sequence.frames] * 2  # 20 frames > the tiny model's horizon of 4
    for color in frames[1:]:
        masks = tracker.track(color)
        assert masks[1].shape == (SMALL.height, SMALL.width)
    session = tracker.session
    assert list(session.processed_frames) == [tracker.frame_idx] == [len(frames) - 1]
    assert tracker.stored_frames <= tracker.horizon + 1  # the prompted frame + the model's memory horizon
    assert all(min(o["non_cond_frame_outputs"]) >= len(frames) - tracker.horizon
               for o in session.output_dict_per_obj.values())


def test_edgetam_is_a_drop_in_tracker(tmp_path, sequence):
    model, processor = load_tracker(str(save_tiny_edgetam_video(tmp_path / "edgetam")))
    assert type(model).__name__ == "EdgeTamVideoModel"
    tracker = StreamingTracker(model, processor)
    assert tracker.start(sequence.frames[0].color, {1: BOX})[1].any()
    for frame in sequence.frames[1:7]:
        assert tracker.track(frame.color)[1].shape == (SMALL.height, SMALL.width)
    assert len(tracker.session.processed_frames) == 1 and tracker.stored_frames <= tracker.horizon + 1


def test_segmenter_detects_then_tracks_object_and_handle(checkpoints, sequence):
    config = _config(checkpoints, box_threshold=0.0, text_threshold=0.0, min_area_ratio=0.0, min_iou=0.0)
    segmenter = make_segmenter("gdino-sam2", config)
    mask = segmenter.start(sequence.frames[0], "cabinet")
    assert mask.shape == (SMALL.height, SMALL.width) and mask.any()
    handle = segmenter.handle_mask(sequence.frames[0])
    assert handle is not None and handle.shape == mask.shape
    for frame in sequence.frames[1:]:
        assert segmenter.track(frame).shape == mask.shape
    assert segmenter.redetections == 0


def test_box_skips_detection(checkpoints, sequence):
    config = _config(checkpoints, box=BOX, handle_prompt=None, min_area_ratio=0.0, min_iou=0.0)
    segmenter = make_segmenter("gdino-sam2", config)
    assert segmenter.detector is None  # nothing to detect: the detector is not even loaded
    assert segmenter.start(sequence.frames[0]).any()
    assert segmenter.handle_mask(sequence.frames[0]) is None


def test_lost_track_is_redetected(checkpoints, sequence):
    # min_iou 1: any change of the mask counts as lost; each re-detection then gives a plausible mask
    config = _config(checkpoints, box_threshold=0.0, text_threshold=0.0, min_area_ratio=0.0, min_iou=1.0)
    segmenter = make_segmenter("gdino-sam2", config)
    segmenter.start(sequence.frames[0])
    for frame in sequence.frames[1:]:
        segmenter.track(frame)
    assert segmenter.redetections >= 1
    assert segmenter.tracker.frame_idx < len(sequence.frames) - 1  # the session was re-prompted on a later frame


def test_unrecoverable_track_stops_with_one_clear_error(checkpoints, sequence):
    import torch

    segmenter = make_segmenter("gdino-sam2", _config(checkpoints, box=BOX, handle_prompt=None, max_redetections=2))
    segmenter.start(sequence.frames[0])
    segmenter.track(sequence.frames[1])
    before = segmenter.redetections
    # from now on the tracker's object-score head says "absent": every mask, re-prompted or not, is empty
    with torch.no_grad():
        segmenter.tracker.model.mask_decoder.pred_obj_score_head.proj_out.bias.fill_(-5.0)
    with pytest.raises(PerceptionError, match=r"lost track of 'cabinet' at frame 2: mask area 0 px .*"
                                              r"re-detection 2 gave an implausible mask; stopped after 2"):
        segmenter.track(sequence.frames[2])
    assert segmenter.redetections == before + 2


def test_missing_object_is_an_actionable_error(checkpoints, sequence):
    segmenter = make_segmenter("gdino-sam2", _config(checkpoints, box_threshold=1.0))
    with pytest.raises(PerceptionError, match="no 'cabinet' found on frame 0 .*--box"):
        segmenter.start(sequence.frames[0])


def test_corrupt_or_mismatched_checkpoint_is_one_model_error(checkpoints, tmp_path):
    broken = shutil.copytree(checkpoints[1], tmp_path / "broken")
    (broken / "model.safetensors").write_bytes(b"not a safetensors file")
    with pytest.raises(ModelError, match="does not load .*corrupt"):
        load_tracker(str(broken))
    (broken / "config.json").unlink()
    with pytest.raises(ModelError, match="config.json is missing"):
        load_tracker(str(broken))
    with pytest.raises(ModelError, match="is a 'grounding-dino' model, not a tracker"):
        load_tracker(str(checkpoints[0]))
    with pytest.raises(ModelError, match="model.safetensors is a file, not a model directory; point --detector"):
        load_tracker(str(broken / "model.safetensors"))


def test_model_found_in_the_hugging_face_cache(checkpoints, tmp_path, monkeypatch):
    import huggingface_hub.constants

    snapshot = tmp_path / "hub" / "models--acme--tiny-sam2" / "snapshots" / "abc123"
    shutil.copytree(checkpoints[1], snapshot)
    (tmp_path / "hub" / "models--acme--tiny-sam2" / "refs").mkdir()
    (tmp_path / "hub" / "models--acme--tiny-sam2" / "refs" / "main").write_text("abc123")
    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_CACHE", str(tmp_path / "hub"))
    assert resolve_checkpoint("acme/tiny-sam2") == snapshot
    model, _ = load_tracker("acme/tiny-sam2")
    assert type(model).__name__ == "Sam2VideoModel"
    with pytest.raises(ModelError, match="acme/absent is not in the Hugging Face cache; fetch it with "
                                         "`hf download acme/absent`"):
        load_detector("acme/absent")


def test_models_check_reports_presence_and_fetch_command(checkpoints, tmp_path, capsys, monkeypatch):
    statuses = check_models([("detector", str(checkpoints[0])), ("tracker", "acme/absent")])
    assert statuses[0].loads and statuses[0].location == str(checkpoints[0])
    assert not statuses[1].loads and statuses[1].fetch == "hf download acme/absent"
    assert main(["models", "check", "--detector", str(checkpoints[0]), "--tracker", str(checkpoints[1]),
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [m["loads"] for m in data["models"] if m["required"]] == [True, True]
    assert main(["models", "check", "--tracker", str(tmp_path / "nowhere"), "--json"]) == 1
    capsys.readouterr()
    (tmp_path / "half").mkdir()  # a local folder given without ./, whose config.json lacks model_type
    (tmp_path / "half" / "config.json").write_text("{}")
    monkeypatch.chdir(tmp_path)
    assert main(["models", "check", "--tracker", "half", "--json"]) == 1
    message = next(m["message"] for m in json.loads(capsys.readouterr().out)["models"] if m["role"] == "tracker")
    assert "half/config.json names no model_type" in message and "hf download" not in message


def test_track_cli_writes_masks_and_overlay(checkpoints, sequence, tmp_path, capsys):
    write_sequence(sequence, tmp_path / "rec")
    out = tmp_path / "tracked"
    code = main(["track", str(tmp_path / "rec"), "--detector", str(checkpoints[0]), "--tracker", str(checkpoints[1]),
                 "--box", *map(str, BOX), "--out", str(out), "--device", "cpu", "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    data = json.loads(captured.out)
    assert data["frames"] == len(sequence.frames) and data["segmenter"] == "gdino-sam2"
    recording = FramesRecording(out)
    assert recording.has_masks and len(recording) == len(sequence.frames)
    assert (out / "overlay.png").stat().st_size > 0 and (out / "truth.json").exists()


def test_tracker_takes_point_prompts_alone_or_with_boxes(checkpoints, sequence):
    tracker = StreamingTracker(*load_tracker(str(checkpoints[1])))
    color = sequence.frames[0].color
    alone = tracker.start(color, {}, {1: [(75.0, 60.0)]})
    assert set(alone) == {1} and alone[1].shape == (SMALL.height, SMALL.width)
    both = tracker.start(color, {2: (60.0, 40.0, 90.0, 60.0)}, {1: [(75.0, 60.0), (70.0, 50.0)]})
    assert set(both) == {1, 2}
    assert tracker.track(sequence.frames[1].color).keys() == {1, 2}
    with pytest.raises(ValueError, match="at least one box or point"):
        tracker.start(color, {})


def test_the_users_point_prompts_the_tracker_without_detecting_the_object(checkpoints, sequence, monkeypatch):
    config = _config(checkpoints, point=(75.0, 60.0), handle_prompt=None, min_area_ratio=0.0, min_iou=0.0)
    segmenter = make_segmenter("gdino-sam2", config)
    assert segmenter.detector is None  # the point names the object: no detector loaded
    prompts = []
    start = segmenter.tracker.start
    monkeypatch.setattr(segmenter.tracker, "start", lambda color, boxes, points=None: prompts.append(
        (dict(boxes), dict(points or {}))) or start(color, boxes, points))
    mask = segmenter.start(sequence.frames[0])
    assert prompts == [({}, {1: [(75.0, 60.0)]})]
    assert mask.shape == (SMALL.height, SMALL.width)
    with pytest.raises(PerceptionError, match=r"--point 400 60 is outside the 160x120 image"):
        make_segmenter("gdino-sam2", _config(checkpoints, point=(400.0, 60.0), handle_prompt=None)).start(
            sequence.frames[0])


def test_a_point_with_a_handle_prompt_looks_for_the_handle_in_the_points_mask(checkpoints, sequence):
    config = _config(checkpoints, point=(75.0, 60.0), box_threshold=0.0, text_threshold=0.0, min_area_ratio=0.0,
                     min_iou=0.0)
    segmenter = make_segmenter("gdino-sam2", config)
    mask = segmenter.start(sequence.frames[0])
    assert mask.shape == (SMALL.height, SMALL.width)
    handle = segmenter.handle_mask(sequence.frames[0])
    assert handle is None or handle.shape == mask.shape
