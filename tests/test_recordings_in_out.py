"""Recordings in and out: each export layout converts back (frames, depth in metres within the unit, intrinsics,
poses), others' TUM RGB-D and Open3D folders convert, and the LeRobot export passes the format's own checks."""

import json

import cv2
import numpy as np
import open3d as o3d
import pytest
from cli_run import run
from lerobot_format import check_dataset

from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesWriter

INTR = Intrinsics(64, 48, 60.0, 61.0, 31.5, 23.5)
TIMES = [0.0, 0.2, 0.4, 0.9, 1.1, 1.3]  # a pause between two motions, as a run has


def pose(i: int) -> np.ndarray:
    """A camera on the arm: it turns and moves with every frame."""
    c, s = np.cos(0.1 * i), np.sin(0.1 * i)
    T = np.array([[c, -s, 0.0, 0.1 * i], [s, c, 0.0, -0.05], [0.0, 0.0, 1.0, 0.8], [0.0, 0.0, 0.0, 1.0]])
    return T @ np.array([[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def write_run(path, masks=True):
    """A recording as a run writes it: moving camera, joints, commands, gripper opening, tool poses."""
    rng = np.random.default_rng(3)
    with FramesWriter(path, INTR, T_base_camera=pose(0), camera="sim", simulated=True, robot="panda_sim") as w:
        for i, t in enumerate(TIMES):
            color = np.zeros((48, 64, 3), np.uint8)
            color[:, :, 0] = np.linspace(0, 255, 64).astype(np.uint8)[None, :]
            color[:, :, 1] = 40 * i
            depth = rng.uniform(0.4, 2.5, (48, 64)).astype(np.float32)
            depth[:4] = 0.0
            mask = np.zeros((48, 64), bool)
            mask[10:30, 20:50] = True
            q = np.linspace(-1, 1, 7) + 0.05 * i
            w.write(Frame(i, t, color, depth, INTR, pose(i), mask=mask if masks else None), joint_positions=q,
                    joint_commands=q + 0.01, gripper_width_m=0.08 - 0.01 * i, ee_pose=pose(i), grasped=i > 0)


@pytest.mark.parametrize("fmt, unit", [("tum", 1 / 5000), ("open3d", 1 / 1000)])
def test_an_export_converts_back_to_the_recording(capsys, tmp_path, fmt, unit):
    write_run(tmp_path / "rec")
    code, out, err = run(capsys, "export", tmp_path / "rec", "--format", fmt, "--out", tmp_path / fmt, "--json")
    assert code == 0, err
    code, out, err = run(capsys, "convert", tmp_path / fmt, "--out", tmp_path / "back", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["source"] == fmt and summary["source_depth_scale"] == pytest.approx(unit), err
    original, back = FramesRecording(tmp_path / "rec"), FramesRecording(tmp_path / "back")
    assert len(back) == len(original) and back.intrinsics == original.intrinsics
    for i in range(len(original)):
        a, b = original.frame(i), back.frame(i)
        assert b.t == pytest.approx(a.t, abs=1e-6)
        np.testing.assert_array_equal(b.color, a.color)
        assert np.abs(b.depth_m - a.depth_m).max() <= max(unit, original.depth_scale) + 1e-6  # within the unit
        np.testing.assert_allclose(b.T_base_camera, a.T_base_camera, atol=1e-5)
    if fmt == "tum":  # tool.txt: the held frames' gripper poses
        held = [i for i, r in enumerate(original.records) if r["grasped"]]
        assert [i for i, r in enumerate(back.records) if "ee_pose" in r] == held
        np.testing.assert_allclose(back.records[1]["ee_pose"], original.records[1]["ee_pose"], atol=1e-5)
    else:  # the object's clouds, written by open3d.io in the base frame
        cloud = o3d.io.read_point_cloud(str(tmp_path / fmt / "object" / "000002.ply"))
        assert len(cloud.points) > 0 and np.asarray(cloud.points)[:, 2].min() > -3.0


def test_convert_reads_the_tum_benchmark_layout(capsys, tmp_path):
    """A freiburg1 sequence as the benchmark lays it out: colour and depth stamped apart, depth 5000 units per
    metre, ground truth at its own rate."""
    src = tmp_path / "rgbd_dataset_freiburg1_desk"
    (src / "rgb").mkdir(parents=True)
    (src / "depth").mkdir()
    rgb, depth = ["# color images", "# timestamp filename"], ["# depth maps"]
    truth = ["# timestamp tx ty tz qx qy qz qw"]
    for i in range(5):
        t = 1305031102.175304 + 0.033 * i
        cv2.imwrite(str(src / "rgb" / f"{t:.6f}.png"), np.full((480, 640, 3), 20 * i, np.uint8))
        cv2.imwrite(str(src / "depth" / f"{t + 0.004:.6f}.png"), np.full((480, 640), 5000 + 500 * i, np.uint16))
        rgb.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth.append(f"{t + 0.004:.6f} depth/{t + 0.004:.6f}.png")
    depth.append(f"{t + 1.0:.6f} depth/extra.png")  # no colour image near it: left unpaired
    for k in range(30):
        truth.append(f"{1305031102.1 + 0.01 * k:.4f} {0.01 * k:.4f} 0.0 1.5 0.0 0.0 0.0 1.0")
    for name, lines in (("rgb.txt", rgb), ("depth.txt", depth), ("groundtruth.txt", truth)):
        (src / name).write_text("\n".join(lines) + "\n")
    code, out, err = run(capsys, "convert", src, "--out", tmp_path / "rec", "--json")
    summary = json.loads(out)
    assert code == 0 and summary["frames"] == 5 and summary["unpaired_frames"] == {"color": 0, "depth": 1}, err
    rec = FramesRecording(tmp_path / "rec")
    assert rec.intrinsics == Intrinsics(640, 480, 517.3, 516.5, 318.6, 255.3)  # the benchmark's freiburg1 camera
    for i in range(5):
        frame = rec.frame(i)
        assert frame.t == pytest.approx(0.033 * i, abs=1e-6)
        assert frame.depth_m[0, 0] == pytest.approx(1.0 + 0.1 * i, abs=1e-3)
        assert frame.T_base_camera[0, 3] == pytest.approx(0.075304 + 0.033 * i, abs=1e-4)  # interpolated at t


def test_convert_reads_an_open3d_reconstruction_folder(capsys, tmp_path):
    """Open3D's layout as its RealSense recorder writes it: image/ JPEGs, depth/ in mm, camera_intrinsic.json, no
    times (30 per second) and no poses."""
    src = tmp_path / "o3d"
    (src / "image").mkdir(parents=True)
    (src / "depth").mkdir()
    for i in range(3):
        o3d.io.write_image(str(src / "image" / f"{i:06d}.jpg"), o3d.geometry.Image(np.full((48, 64, 3), 90, np.uint8)))
        o3d.io.write_image(str(src / "depth" / f"{i:06d}.png"), o3d.geometry.Image(np.full((48, 64), 700 + i,
                                                                                           np.uint16)))
    o3d.io.write_pinhole_camera_intrinsic(str(src / "camera_intrinsic.json"),
                                          o3d.camera.PinholeCameraIntrinsic(64, 48, 50.0, 51.0, 32.0, 24.0))
    code, out, err = run(capsys, "convert", src, "--out", tmp_path / "rec", "--json")
    assert code == 0 and json.loads(out)["source"] == "open3d", err
    rec = FramesRecording(tmp_path / "rec")
    assert rec.intrinsics == Intrinsics(64, 48, 50.0, 51.0, 32.0, 24.0) and rec.T_base_camera is None
    assert [rec.frame(i).t for i in range(3)] == pytest.approx([0.0, 1 / 30, 2 / 30])
    assert rec.frame(2).depth_m[5, 5] == pytest.approx(0.702)
    code, _, err = run(capsys, "convert", tmp_path / "rec", "--out", tmp_path / "again")
    assert code == 2 and "expected a RealSense" in err  # a frames directory is not something to convert


def test_convert_names_the_missing_intrinsics(capsys, tmp_path):
    src = tmp_path / "mine"
    (src / "rgb").mkdir(parents=True)
    cv2.imwrite(str(src / "rgb" / "1.0.png"), np.zeros((48, 64, 3), np.uint8))
    (src / "rgb.txt").write_text("1.0 rgb/1.0.png\n")
    (src / "depth.txt").write_text("1.0 rgb/1.0.png\n")
    code, _, err = run(capsys, "convert", src, "--out", tmp_path / "rec")
    assert code == 2 and "no camera_intrinsic.json" in err and not (tmp_path / "rec").exists()


def test_lerobot_export_passes_the_format_checks_with_the_arm(capsys, tmp_path):
    write_run(tmp_path / "rec")
    code, out, err = run(capsys, "export", tmp_path / "rec", "--format", "lerobot", "--out", tmp_path / "ds",
                         "--fps", 10, "--json")
    assert code == 0, err
    dataset = check_dataset(tmp_path / "ds")
    info, data = dataset["info"], dataset["data"]
    assert info["fps"] == 10 and info["total_frames"] == 14 and info["robot_type"] == "panda_sim"  # 1.3 s at 10 Hz
    assert info["features"]["observation.state"]["names"][-1] == "gripper_width_m"
    picks = [0, 0, 1, 1, 2, 2, 2, 2, 2, 3, 3, 4, 4, 5]  # the latest frame at each tenth of a second
    rec = FramesRecording(tmp_path / "rec")
    state = np.array(data.column("observation.state").to_pylist())
    action = np.array(data.column("action").to_pylist())
    for k, i in enumerate(picks):
        np.testing.assert_allclose(state[k], [*rec.records[i]["joint_positions"], rec.records[i]["gripper_width_m"]],
                                   atol=1e-6)
        np.testing.assert_allclose(action[k], rec.records[i]["joint_commands"], atol=1e-6)
        assert np.abs(dataset["videos"]["observation.images.color"][k].astype(int) - rec.frame(i).color).mean() < 8
    code, _, err = run(capsys, "export", tmp_path / "rec", "--format", "lerobot", "--out", tmp_path / "ds")
    assert code == 2 and "--overwrite" in err  # an earlier export is replaced only when asked
