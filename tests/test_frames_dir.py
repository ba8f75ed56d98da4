"""The frames-directory recording format: round trip, interrupted recordings, corrupt input, replay."""

import json
import time

import cv2
import numpy as np
import pytest
from cli_run import one_line, run

from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesReplayCamera, FramesWriter
from drivers.errors import RecordingError

INTR = Intrinsics(32, 24, 30.0, 31.0, 15.5, 11.5)
T_BC = np.array([[0.0, 0.0, 1.0, 0.1], [-1.0, 0.0, 0.0, 0.2], [0.0, -1.0, 0.0, 0.9], [0.0, 0.0, 0.0, 1.0]])


def make_frames(n: int, seed: int = 0) -> list[Frame]:
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n):
        color = rng.integers(0, 256, (INTR.height, INTR.width, 3), dtype=np.uint8)
        depth = rng.uniform(0.3, 3.0, (INTR.height, INTR.width)).astype(np.float32)
        depth[rng.random(depth.shape) < 0.1] = 0.0
        mask = rng.random(depth.shape) < 0.3
        frames.append(Frame(i, 0.1 * i, color, depth, INTR, mask=mask))
    return frames


def ee(i: int) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = [0.5 + 0.01 * i, -0.1, 0.7]
    return pose


def record(path, n=4, masks=True, seed=0, replace=False) -> list[Frame]:
    frames = make_frames(n, seed)
    with FramesWriter(path, INTR, T_base_camera=T_BC, replace=replace) as writer:
        for i, frame in enumerate(frames):
            if not masks:
                frame.mask = None
            writer.write(frame, joint_positions=[0.1 * i, 0.2], ee_pose=ee(i))  # mask defaults to frame.mask
    return frames


def test_round_trip(tmp_path):
    frames = record(tmp_path / "rec")
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == 4 and rec.has_masks
    assert rec.intrinsics == INTR and rec.depth_scale == 0.001
    np.testing.assert_array_equal(rec.T_base_camera, T_BC)
    for i, original in enumerate(frames):
        frame = rec.frame(i)
        assert frame.index == i and frame.t == pytest.approx(original.t)
        np.testing.assert_array_equal(frame.color, original.color)
        assert frame.depth_m.dtype == np.float32
        assert np.max(np.abs(frame.depth_m - original.depth_m)) <= 0.0005 + 1e-6
        np.testing.assert_array_equal(frame.depth_m == 0, original.depth_m == 0)
        np.testing.assert_array_equal(frame.mask, original.mask)
        np.testing.assert_array_equal(frame.T_base_camera, T_BC)
        assert rec.records[i]["joint_positions"] == pytest.approx([0.1 * i, 0.2])
        np.testing.assert_allclose(rec.records[i]["ee_pose"], ee(i))


def test_colour_is_stored_as_rgb_png(tmp_path):
    frames = record(tmp_path / "rec", n=1)
    bgr = cv2.imread(str(tmp_path / "rec" / "color" / "000000.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(bgr[..., ::-1], frames[0].color)
    depth = cv2.imread(str(tmp_path / "rec" / "depth" / "000000.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16


def test_depth_scale_and_out_of_range_depth(tmp_path):
    depth = np.full((INTR.height, INTR.width), 1.0, np.float32)
    depth[0, :4] = [np.nan, -1.0, np.inf, 100.0]
    frame = Frame(0, 0.0, np.zeros((INTR.height, INTR.width, 3), np.uint8), depth, INTR)
    with FramesWriter(tmp_path / "rec", INTR, depth_scale=0.0002) as writer:
        writer.write(frame)
    got = FramesRecording(tmp_path / "rec").frame(0)
    assert list(got.depth_m[0, :4]) == pytest.approx([0.0, 0.0, 0.0, 0.0])  # 100 m does not fit 16 bits: no depth
    assert got.depth_m[5, 5] == pytest.approx(1.0, abs=0.0001)
    assert got.mask is None and got.T_base_camera is None


def test_without_masks(tmp_path):
    record(tmp_path / "rec", masks=False)
    rec = FramesRecording(tmp_path / "rec")
    assert not rec.has_masks and rec.frame(0).mask is None


def test_truncated_last_jsonl_line_is_dropped(tmp_path):
    record(tmp_path / "rec")
    jsonl = tmp_path / "rec" / "frames.jsonl"
    text = jsonl.read_text()
    jsonl.write_text(text[: len(text) - 20])  # cut inside the last line
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == 3
    assert rec.frame(2).index == 2


def test_missing_last_png_is_dropped(tmp_path):
    record(tmp_path / "rec")
    (tmp_path / "rec" / "depth" / "000003.png").unlink()
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == 3
    assert rec.frame(-1).index == 2


def test_meta_only_recording_has_no_frames(tmp_path):
    FramesWriter(tmp_path / "rec", INTR).close()
    assert len(FramesRecording(tmp_path / "rec")) == 0
    with pytest.raises(RecordingError, match="no frames"):
        FramesReplayCamera(tmp_path / "rec").read()


def edit_meta(path, **changes):
    meta = json.loads((path / "meta.json").read_text())
    for key, value in changes.items():
        if key == "drop_fx":
            del meta["intrinsics"]["fx"]
        elif key == "width":
            meta["intrinsics"]["width"] = value
        else:
            meta[key] = value
    (path / "meta.json").write_text(json.dumps(meta))


def write_png(path, image):
    assert cv2.imwrite(str(path), image)


CORRUPTIONS = {
    "no meta": (lambda p: (p / "meta.json").unlink(), "meta.json is missing"),
    "bad json": (lambda p: (p / "meta.json").write_text("{not json"), "not valid JSON"),
    "wrong format": (lambda p: edit_meta(p, format="rosbag"), "expected 'axisloop-frames'"),
    "version 2": (lambda p: edit_meta(p, version=2), "unsupported format version 2"),
    "missing fx": (lambda p: edit_meta(p, drop_fx=True), "fx missing"),
    "bad pose": (lambda p: edit_meta(p, T_base_camera=[[1, 0], [0, 1]]), "T_base_camera must be a 4x4"),
    "bad scale": (lambda p: edit_meta(p, depth_scale=-1), "depth_scale must be positive"),
}


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corrupt_meta_raises_on_open(tmp_path, case):
    record(tmp_path / "rec", n=2)
    corrupt, message = CORRUPTIONS[case]
    corrupt(tmp_path / "rec")
    with pytest.raises(RecordingError, match=message) as info:
        FramesRecording(tmp_path / "rec")
    assert "meta.json" in str(info.value)


FRAME_CORRUPTIONS = {
    "missing colour": (lambda p: (p / "color" / "000001.png").unlink(), "000001.png is missing"),
    "8-bit depth": (lambda p: write_png(p / "depth" / "000001.png", np.zeros((24, 32), np.uint8)), "uint8"),
    "grey colour": (lambda p: write_png(p / "color" / "000001.png", np.zeros((24, 32), np.uint8)), "1 chan"),
    "16-bit colour": (
        lambda p: write_png(p / "color" / "000001.png", np.zeros((24, 32, 3), np.uint16)),
        "uint16",
    ),
    "size mismatch": (lambda p: edit_meta(p, width=40), "intrinsics say 40x24"),
    "garbage png": (lambda p: (p / "color" / "000001.png").write_bytes(b"oops"), "not a readable PNG"),
}


@pytest.mark.parametrize("case", sorted(FRAME_CORRUPTIONS))
def test_corrupt_frame_raises_on_read(tmp_path, case):
    record(tmp_path / "rec", n=3)
    corrupt, message = FRAME_CORRUPTIONS[case]
    corrupt(tmp_path / "rec")
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == 3
    with pytest.raises(RecordingError, match=message):
        rec.frame(1)


def test_corrupt_middle_jsonl_line(tmp_path):
    record(tmp_path / "rec", n=3)
    jsonl = tmp_path / "rec" / "frames.jsonl"
    lines = jsonl.read_text().splitlines()
    lines[1] = '{"t": 0.1}'
    jsonl.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match="line 2"):
        len(FramesRecording(tmp_path / "rec"))


def test_grasped_is_written_only_when_given_and_gates_the_gripper_pose(tmp_path):
    """A writer that knows when the gripper held the handle marks the frames; a reader then takes the gripper's
    pose as the handle's only on the frames marked true (a frame without the mark in such a recording too)."""
    frames = make_frames(4)
    with FramesWriter(tmp_path / "rec", INTR) as writer:
        for i, grasped in enumerate((None, False, True, True)):
            writer.write(frames[i], ee_pose=ee(i), grasped=grasped)
    rec = FramesRecording(tmp_path / "rec")
    assert [r.get("grasped", "absent") for r in rec.records] == ["absent", False, True, True]
    assert rec.marks_grasp and rec.held_pose(0) is None and rec.held_pose(1) is None
    np.testing.assert_array_equal(rec.held_pose(2), ee(2))
    record(tmp_path / "unmarked", n=3)  # no writer said: every pose is the handle's, as before
    unmarked = FramesRecording(tmp_path / "unmarked")
    assert not unmarked.marks_grasp and "grasped" not in unmarked.records[0]
    np.testing.assert_array_equal(unmarked.held_pose(0), ee(0))


@pytest.mark.parametrize(("value", "shown"), [(1, "1"), ("yes", '"yes"'), (None, "null"), ([True], "[true]")])
def test_a_grasped_that_is_not_true_or_false_is_one_line_naming_file_line_cause_and_fix(capsys, tmp_path, value,
                                                                                         shown):
    record(tmp_path / "rec", n=3)
    jsonl = tmp_path / "rec" / "frames.jsonl"
    lines = [json.loads(line) for line in jsonl.read_text().splitlines()]
    lines[1]["grasped"] = value
    jsonl.write_text("".join(json.dumps(line) + "\n" for line in lines))
    with pytest.raises(RecordingError) as caught:
        len(FramesRecording(tmp_path / "rec"))
    assert str(caught.value) == (f"{jsonl}, line 2: not a frame record (grasped is {shown}, not true or false); "
                                 "write grasped as the JSON boolean true or false, or remove the key")
    code, _, err = run(capsys, "axis", "estimate", tmp_path / "rec")
    assert code == 2 and one_line(err) == f"error: {caught.value}"


def test_missing_directory(tmp_path):
    with pytest.raises(RecordingError, match="not found"):
        FramesRecording(tmp_path / "nope")


def test_every_command_that_reads_a_recording_takes_a_run_folder_for_it(capsys, tmp_path):
    """`axis estimate RUN`, `track RUN`, `export RUN`, `--camera replay:RUN` (record, snapshot, open --dry-run):
    RUN is a run folder, its recording RUN/frames."""
    run_dir = tmp_path / "run"
    record(run_dir / "frames", n=3)
    (run_dir / "steps.json").write_text("[]")
    assert FramesRecording(run_dir).path == run_dir / "frames" and len(FramesReplayCamera(run_dir).recording) == 3
    code, out, err = run(capsys, "axis", "estimate", run_dir, "--json")
    assert code in (0, 1) and len(json.loads(out)["steps"]) == 3, err  # 3 frames read (no axis from them)
    code, out, err = run(capsys, "track", run_dir, "--segmenter", "classical", "--box", 0, 0, 16, 12, "--out",
                         tmp_path / "tracked")
    assert code == 2 and "on frame 0" in err, err  # the run's first frame reached the segmenter (random pixels)
    code, out, err = run(capsys, "export", run_dir, "--format", "tum", "--out", tmp_path / "tum", "--json")
    assert code == 0 and json.loads(out)["frames"] == 3, err
    code, _, err = run(capsys, "record", "--camera", f"replay:{run_dir}", "--frames", 2, "--out", tmp_path / "x")
    assert code == 0 and len(FramesRecording(tmp_path / "x")) == 2, err
    code, _, err = run(capsys, "cameras", "snapshot", "--camera", f"replay:{run_dir}", "--out", tmp_path / "snap")
    assert code == 0 and (tmp_path / "snap" / "depth.png").is_file(), err
    code, _, err = run(capsys, "record", "--camera", f"replay:{run_dir}", "--frames", 1, "--out", run_dir / "x")
    assert code == 2 and "lies inside the recording" in err  # writing into the run folder read is refused


def test_writer_refuses_foreign_directory_and_replaces_a_recording(tmp_path):
    (tmp_path / "stuff").mkdir()
    (tmp_path / "stuff" / "notes.txt").write_text("keep me")
    with pytest.raises(RecordingError, match="not a frames recording"):
        FramesWriter(tmp_path / "stuff", INTR)
    assert (tmp_path / "stuff" / "notes.txt").read_text() == "keep me"

    record(tmp_path / "rec", n=4)
    (tmp_path / "rec" / "truth.json").write_text("{}")
    with pytest.raises(RecordingError, match="a recording is already there"):  # never replaced unasked
        record(tmp_path / "rec", n=2, masks=False, seed=1)
    assert len(FramesRecording(tmp_path / "rec")) == 4
    record(tmp_path / "rec", n=2, masks=False, seed=1, replace=True)
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == 2 and not rec.has_masks
    assert not (tmp_path / "rec" / "color" / "000003.png").exists() and not (tmp_path / "rec" / "truth.json").exists()


def test_writer_rejects_frames_of_the_wrong_size(tmp_path):
    frame = make_frames(1)[0]
    frame.color = frame.color[:, :10]
    with FramesWriter(tmp_path / "rec", INTR) as writer:
        with pytest.raises(RecordingError, match="colour must be"):
            writer.write(frame)


def test_replay_camera_end_and_loop(tmp_path):
    frames = record(tmp_path / "rec", n=3)
    with FramesReplayCamera(tmp_path / "rec") as camera:
        assert camera.intrinsics == INTR
        got = [camera.read() for _ in range(3)]
        with pytest.raises(RecordingError, match="end of recording"):
            camera.read()
    np.testing.assert_array_equal(got[2].color, frames[2].color)
    np.testing.assert_array_equal(got[1].mask, frames[1].mask)

    with FramesReplayCamera(tmp_path / "rec", loop=True) as camera:
        looped = [camera.read() for _ in range(7)]
    assert [f.index for f in looped] == list(range(7))
    assert np.all(np.diff([f.t for f in looped]) == pytest.approx(0.1))
    np.testing.assert_array_equal(looped[4].color, frames[1].color)


def test_replay_camera_realtime(tmp_path):
    record(tmp_path / "rec", n=3)
    start = time.monotonic()
    with FramesReplayCamera(tmp_path / "rec", realtime=True) as camera:
        for _ in range(3):
            camera.read()
    assert time.monotonic() - start >= 0.2 - 0.01
