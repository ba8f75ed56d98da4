"""Recordings and trajectory files as users bring them: a frame without its mask, no frames, depth beyond the
16-bit range, a float-depth ROS 2 bag, repeated times, a broken last line, too few or BOM-prefixed trajectory
samples, and what `deploy sim record` and `deploy axis estimate` report."""

import json

import cv2
import numpy as np
import pytest

from deploy.cli import main
from deploy.synthetic.sequence import synthetic_sequence
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesWriter
from drivers.camera.realsense_convert import convert_recording
from drivers.camera.snapshot import save_snapshot
from drivers.errors import RecordingError
from sim_fallback.scripted import record_scripted

SMALL = Intrinsics(16, 12, 15.0, 15.0, 7.5, 5.5)


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def still_frame(index: int, t: float, depth_m: float = 1.0) -> Frame:
    return Frame(index=index, t=t, color=np.full((12, 16, 3), 90, np.uint8),
                 depth_m=np.full((12, 16), depth_m, np.float32), intrinsics=SMALL)


@pytest.fixture(scope="module")
def drawer(tmp_path_factory):
    """A synthetic drawer opening 10 cm over 8 frames, with gripper poses; the last frame's mask is empty, so
    that frame gives no axis."""
    seq = synthetic_sequence("drawer", np.random.default_rng(5), travel=0.10, n_frames=8)
    path = tmp_path_factory.mktemp("rec") / "drawer"
    with FramesWriter(path, seq.frames[0].intrinsics, T_base_camera=seq.T_base_camera) as writer:
        for k, (frame, pose) in enumerate(zip(seq.frames, seq.gripper_poses, strict=True)):
            writer.write(frame, mask=frame.mask if k < 7 else np.zeros_like(frame.mask), ee_pose=pose)
    return path


def test_a_frame_without_its_mask_is_named_with_the_fix(capsys, drawer, tmp_path):
    damaged = tmp_path / "damaged"
    with FramesWriter(damaged, SMALL) as writer:
        for k in range(4):
            writer.write(still_frame(k, k * 0.1), mask=None if k == 2 else np.ones((12, 16), bool))
    code, _, err = run(capsys, "axis", "estimate", damaged)
    assert code == 2 and "Traceback" not in err
    assert err.count("\n") == 1 and "frame 2 has no mask" in err and "deploy track" in err
    assert FramesRecording(damaged).unmasked == [2]


def test_a_recording_without_frames_says_so(capsys, tmp_path):
    FramesWriter(tmp_path / "empty", SMALL).close()
    code, _, err = run(capsys, "axis", "estimate", tmp_path / "empty")
    assert code == 2 and "has no frames" in err and "mask" not in err


def test_the_last_axis_any_frame_gave_is_reported_with_its_frame(capsys, drawer):
    code, out, _ = run(capsys, "axis", "estimate", drawer, "--estimator", "paper-obb", "--joint", "prismatic",
                       "--json")
    data = json.loads(out)
    assert data["steps"][-1]["joint_type"] is None and data["steps"][-2]["joint_type"] == "prismatic"
    assert code == 0 and data["joint_type"] == "prismatic" and data["from_frame"] == 6 and "reason" not in data
    assert data["direction"] == data["steps"][-2]["direction"]


def test_gripper_path_says_whether_the_estimator_used_it(capsys, drawer):
    for estimator, used in (("screw", False), ("paper-obb", False), ("screw-grip", True), ("trajectory", True)):
        code, out, _ = run(capsys, "axis", "estimate", drawer, "--estimator", estimator, "--joint", "prismatic",
                           "--json")
        assert code == 0 and json.loads(out)["gripper_path"] is used, estimator


def test_depth_beyond_the_16_bit_range_is_no_depth_not_a_wrong_depth(tmp_path):
    with FramesWriter(tmp_path / "fine", SMALL, depth_scale=1e-5) as writer:
        writer.write(still_frame(0, 0.0, depth_m=0.5))
        writer.write(still_frame(1, 0.1, depth_m=1.002))  # 100200 units: beyond 65535
    recording = FramesRecording(tmp_path / "fine")
    assert recording.frame(0).depth_m[0, 0] == pytest.approx(0.5, abs=1e-5)
    assert not recording.frame(1).depth_m.any()
    save_snapshot(still_frame(2, 0.2, depth_m=1.002), tmp_path / "snap", depth_scale=1e-5)  # `deploy cameras snapshot`
    assert not cv2.imread(str(tmp_path / "snap" / "depth.png"), cv2.IMREAD_UNCHANGED).any()


def write_float_depth_bag(path, frames: int):
    """A realsense-ros bag with aligned 32FC1 depth (metres): 1.002 m, and NaN at one pixel per frame."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    T = store.types
    image_type, info_type = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo"
    with Writer(path, version=9) as writer:
        topics = {name: writer.add_connection(f"/camera/camera/{name}", kind, typestore=store) for name, kind in (
            ("color/image_raw", image_type), ("color/camera_info", info_type),
            ("aligned_depth_to_color/image_raw", image_type))}
        for k in range(frames):
            ns = 1_000_000_000 + k * 33_333_333
            header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9,
                                                                                     nanosec=ns % 10**9), frame_id="c")
            depth = np.full((12, 16), 1.002, np.float32)
            depth[0, 0] = np.nan
            messages = {
                "color/camera_info": T[info_type](
                    header=header, height=12, width=16, distortion_model="plumb_bob", d=np.zeros(5),
                    k=np.array([15.0, 0, 7.5, 0, 15.0, 5.5, 0, 0, 1]), r=np.eye(3).ravel(), p=np.zeros(12),
                    binning_x=0, binning_y=0, roi=T["sensor_msgs/msg/RegionOfInterest"](
                        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)),
                "color/image_raw": T[image_type](header=header, height=12, width=16, encoding="rgb8", is_bigendian=0,
                                                 step=48, data=np.full(12 * 48, 90, np.uint8)),
                "aligned_depth_to_color/image_raw": T[image_type](
                    header=header, height=12, width=16, encoding="32FC1", is_bigendian=0, step=64,
                    data=np.frombuffer(depth.tobytes(), np.uint8)),
            }
            for name, message in messages.items():
                writer.write(topics[name], ns, store.serialize_cdr(message, message.__msgtype__))
    return path


def test_convert_counts_depth_beyond_the_range_and_reports_the_bags_unit(tmp_path, capsys):
    bag = write_float_depth_bag(tmp_path / "bag", 3)
    summary = convert_recording(bag, tmp_path / "fine", depth_scale=1e-5)
    assert summary["source_depth_scale"] == 1.0  # 32FC1 is metres
    assert summary["frames"] == 3 and summary["depth_out_of_range_px"] == 3 * (12 * 16 - 1)
    assert main(["convert", str(bag), "--out", str(tmp_path / "cli"), "--depth-scale", "0.00001"]) == 0
    assert "573 depth pixels lay beyond what 16 bits" in " ".join(capsys.readouterr().out.split())
    assert not FramesRecording(tmp_path / "fine").frame(2).depth_m.any()
    summary = convert_recording(bag, tmp_path / "mm", depth_scale=0.001)
    assert summary["depth_out_of_range_px"] == 0
    assert FramesRecording(tmp_path / "mm").frame(2).depth_m[5, 5] == pytest.approx(1.002, abs=1e-6)


@pytest.mark.parametrize("times", [(0.0, 0.1, 0.1), (0.0, 0.2, 0.1)])
def test_frame_times_that_repeat_or_go_back_are_refused_naming_the_line(tmp_path, times):
    with FramesWriter(tmp_path / "rec", SMALL) as writer:
        for k, t in enumerate(times):
            writer.write(still_frame(k, t))
    with pytest.raises(RecordingError, match=r"frames.jsonl, line 3: t 0.1 does not come after line 2's t"):
        len(FramesRecording(tmp_path / "rec"))


def test_a_broken_last_line_is_ignored_even_with_its_newline_but_not_a_broken_middle_line(tmp_path):
    with FramesWriter(tmp_path / "rec", SMALL) as writer:
        for k in range(3):
            writer.write(still_frame(k, k * 0.1))
    jsonl = tmp_path / "rec" / "frames.jsonl"
    lines = jsonl.read_text().splitlines(keepends=True)
    jsonl.write_text("".join(lines) + '{"index": 3, "t": 0.\n')
    assert len(FramesRecording(tmp_path / "rec")) == 3
    jsonl.write_text(lines[0] + '{"index": 1, "t": 0.\n' + lines[2])
    with pytest.raises(RecordingError, match="line 2: not a frame record"):
        len(FramesRecording(tmp_path / "rec"))


@pytest.mark.parametrize("text", ["", "0.1 0.2 0.3\n", "x,y,z\n", "0 0 0\n0.01 0 0\n"])
def test_a_trajectory_file_with_too_few_samples_is_bad_input(capsys, tmp_path, text):
    file = tmp_path / "path.csv"
    file.write_text(text)
    code, out, err = run(capsys, "axis", "fit-trajectory", file)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert str(file) in err and "at least 3" in err


def test_a_csv_with_a_byte_order_mark_is_read(capsys, tmp_path):
    file = tmp_path / "excel.csv"
    rows = "".join(f"{0.01 * k},0.5,0.7\r\n" for k in range(8))
    file.write_bytes(("\ufeffx,y,z\r\n" + rows).encode())
    code, out, err = run(capsys, "axis", "fit-trajectory", file, "--json")
    assert code == 0, err
    assert json.loads(out)["joint_type"] == "prismatic"


def test_sim_record_says_it_is_simulated_and_names_the_camera(tmp_path):
    record_scripted("drawer", 1, tmp_path / "rec", target=0.02, fps=2.0, resolution=(160, 120), world="box")
    meta = json.loads((tmp_path / "rec" / "meta.json").read_text())
    assert meta["simulated"] is True and meta["camera"] == "sim"
    record = FramesRecording(tmp_path / "rec").records[0]
    assert len(record["joint_positions"]) == 7  # the Panda's joints, as docs/recording-format.md says
