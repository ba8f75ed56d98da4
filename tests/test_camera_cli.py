"""`deploy cameras list|snapshot`, `deploy record` and `deploy convert` end to end, on recordings made here."""

import json

import cv2
import numpy as np
import pytest
from cli_run import one_line
from realsense_recordings import scene, write_db3
from rerun_files import entities

from deploy.cli import main
from drivers.camera.frames_dir import FramesRecording


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def db3(tmp_path_factory):
    return write_db3(tmp_path_factory.mktemp("cli") / "session.db3", scene(6))


@pytest.mark.parametrize("command", [("cameras", "list"), ("cameras", "snapshot"), ("record",), ("convert",),
                                     ("export",)])
def test_help_has_an_example(capsys, command):
    code, out, _ = run(capsys, *command, "--help")
    assert code == 0 and "Example" in out


def test_list_without_cameras_is_empty_and_succeeds(capsys):
    code, out, _ = run(capsys, "cameras", "list", "--json")
    assert code == 0 and json.loads(out) == {"cameras": []}
    code, out, _ = run(capsys, "cameras", "list")
    assert code == 0 and "no RealSense camera connected" in out


def test_convert_db3(capsys, db3, tmp_path):
    code, out, _ = run(capsys, "convert", db3, "--out", tmp_path / "frames", "--json")
    assert code == 0
    summary = json.loads(out)
    assert summary["frames"] == 6 and summary["source_depth_scale"] == pytest.approx(1e-4)
    rec = FramesRecording(tmp_path / "frames")
    assert len(rec) == 6 and rec.frame(5).depth_m[23, 29] == pytest.approx(0.8)


def test_record_from_replay_and_replay_the_result(capsys, db3, tmp_path):
    code, out, _ = run(capsys, "record", "--camera", f"replay:{db3}", "--out", tmp_path / "a", "--frames", 4)
    assert code == 0 and "wrote 4 frames" in out
    code, out, _ = run(capsys, "record", "--camera", f"replay:{tmp_path / 'a'}", "--out", tmp_path / "b",
                       "--seconds", 0.05, "--json")
    assert code == 0 and json.loads(out)["frames"] == 2  # t = 0 and 1/30 s: under 0.05 s
    np.testing.assert_array_equal(FramesRecording(tmp_path / "b").frame(1).color,
                                  FramesRecording(tmp_path / "a").frame(1).color)


def test_record_sim(capsys, tmp_path):
    code, out, _ = run(capsys, "record", "--camera", "sim", "--out", tmp_path / "sim", "--frames", 2,
                       "--width", 160, "--height", 120)
    assert code == 0, out
    rec = FramesRecording(tmp_path / "sim")
    assert len(rec) == 2 and rec.intrinsics.width == 160 and rec.T_base_camera is not None


def test_sim_fps_above_the_physics_rate_is_refused_not_lowered(capsys, tmp_path):
    for args in (("record", "--frames", 2), ("cameras", "snapshot")):
        code, _, err = run(capsys, *args, "--camera", "sim", "--fps", 1000, "--out", tmp_path / "x",
                           "--width", 160, "--height", 120)
        assert code == 2 and "--fps 1000 is more than the simulated camera gives" in one_line(err)
        assert "at most 240" in err and "--fps 240 or less" in err and not (tmp_path / "x").exists()
    code, _, err = run(capsys, "record", "--camera", "sim", "--fps", 240, "--frames", 3, "--out", tmp_path / "x",
                       "--width", 160, "--height", 120)
    assert code == 0, err
    assert [r["t"] for r in FramesRecording(tmp_path / "x").records] == pytest.approx([0, 1 / 240, 2 / 240])


def test_a_replay_plays_at_its_recorded_size_and_refuses_another(capsys, db3, tmp_path):
    frames = tmp_path / "frames"
    assert run(capsys, "record", "--camera", f"replay:{db3}", "--out", frames, "--frames", 2)[0] == 0
    for source in (db3, frames):  # 64x48
        for size in (("--width", 1280, "--height", 720), ("--height", 720)):
            for args in (("record", "--frames", 1), ("cameras", "snapshot")):
                code, _, err = run(capsys, *args, "--camera", f"replay:{source}", *size, "--out", tmp_path / "x")
                line = one_line(err)
                assert code == 2 and f"replay:{source} plays its recording at 64x48, not {' '.join(map(str, size))}" \
                    in line and "drop --width and --height" in line, line
                assert not (tmp_path / "x").exists()
    code, _, err = run(capsys, "record", "--camera", f"replay:{frames}", "--width", 64, "--height", 48,
                       "--frames", 1, "--out", tmp_path / "same")
    assert code == 0, err

def test_record_with_the_arm_stores_joints_and_tool_pose_and_views(capsys, tmp_path):
    out = tmp_path / "arm"
    code, printed, err = run(capsys, "record", "--camera", "sim", "--arm", "sim", "--out", out, "--frames", 2,
                             "--width", 160, "--height", 120, "--view", "--json")
    assert code == 0, err
    summary = json.loads(printed)
    assert summary["arm"] and summary["simulated"] and summary["rrd"] == str(out / "recording.rrd")
    rec = FramesRecording(out)
    assert rec.simulated and rec.camera == "sim" and rec.robot == "panda_sim"  # the joints' robot, named
    for record in rec.records:
        assert len(record["joint_positions"]) == 7 and np.shape(record["ee_pose"]) == (4, 4)
    assert 0.2 < record["ee_pose"][2][3] < 1.2  # the Panda's tool, above the floor
    found = entities(out / "recording.rrd")
    assert found["/world/camera/image/color"]["rows"] == 2 and found["/world/gripper"]["rows"] == 2
    assert found["/joints/panda_joint1/measured"]["rows"] == 2  # the joints read with each frame, and the robot:
    assert "/world/panda/visual_geometries/panda_hand/visual_0" in found


def test_snapshot(capsys, db3, tmp_path):
    code, out, _ = run(capsys, "cameras", "snapshot", "--camera", f"replay:{db3}", "--out", tmp_path / "s", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["intrinsics"]["fx"] == 50.0 and len(data["files"]) == 4
    depth = cv2.imread(str(tmp_path / "s" / "depth.png"), cv2.IMREAD_UNCHANGED)
    meta = json.loads((tmp_path / "s" / "intrinsics.json").read_text())
    assert depth.dtype == np.uint16 and depth[23, 29] * meta["depth_scale"] == pytest.approx(0.8)
    coloured = cv2.imread(str(tmp_path / "s" / "depth_color.png"))
    assert coloured.shape == (48, 64, 3) and (coloured[0, 0] == 0).all() and coloured[23, 29].any()


def test_snapshot_never_replaces_unasked_nor_writes_among_other_files(capsys, db3, tmp_path):
    """A second snapshot to the same --out is refused without --overwrite (before: its 4 files silently
    replaced), and a folder holding anything else is refused even with it (before: written into)."""
    snap = tmp_path / "snap"
    args = ("cameras", "snapshot", "--camera", f"replay:{db3}")
    assert run(capsys, *args, "--out", snap)[0] == 0
    (snap / "color.png").write_bytes(b"earlier")  # to see it kept
    code, _, err = run(capsys, *args, "--out", snap)
    assert code == 2 and one_line(err) == (f"error: --out {snap}: a snapshot is already there: pass --overwrite to "
                                           "replace it, or choose another --out")
    assert (snap / "color.png").read_bytes() == b"earlier"
    assert run(capsys, *args, "--out", snap, "--overwrite")[0] == 0
    assert cv2.imread(str(snap / "color.png")).shape == (48, 64, 3)
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "notes.txt").write_text("mine")
    for extra in ((), ("--overwrite",)):
        code, _, err = run(capsys, *args, "--out", junk, *extra)
        assert code == 2 and one_line(err) == (
            f"error: --out {junk} holds notes.txt, which deploy cameras snapshot never writes there: refusing to "
            "write into the folder, even with --overwrite; move notes.txt out, or choose another --out")
        assert [p.name for p in junk.iterdir()] == ["notes.txt"] and (junk / "notes.txt").read_text() == "mine"
    (tmp_path / "file").write_text("mine")
    code, _, err = run(capsys, *args, "--out", tmp_path / "file")
    assert code == 2 and "is a file, not a snapshot folder" in one_line(err)


@pytest.mark.parametrize("args, message", [
    (("record", "--camera", "kinect", "--out", "x", "--frames", 1), "unknown camera 'kinect'"),
    (("record", "--camera", "sim", "--out", "x"), "--seconds S or --frames N"),
    (("record", "--camera", "d415", "--out", "x", "--frames", 1), "no RealSense camera is connected"),
    (("record", "--camera", "d415", "--out", "x", "--frames", 1, "--width", 100), "resolution 100x480"),
    (("cameras", "snapshot", "--camera", "d415:1234", "--out", "x"), "no RealSense camera is connected"),
    (("convert", "missing.db3", "--out", "x"), "not found"),
    (("convert", "notes.txt", "--out", "x"), "expected a RealSense .bag or .db3"),
])
def test_bad_input_is_one_red_line(capsys, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *args)
    assert code == 2 and "Traceback" not in err
    assert message in " ".join(err.split())


def test_corrupt_frames_directory_via_replay(capsys, tmp_path):
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "meta.json").write_text("{not json")
    code, _, err = run(capsys, "record", "--camera", f"replay:{tmp_path / 'rec'}", "--out", tmp_path / "o",
                       "--frames", 1)
    assert code == 2 and "meta.json is not valid JSON" in " ".join(err.split())
