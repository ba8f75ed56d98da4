"""`deploy convert` on ROS 2 bags of realsense-ros topics (rosbag2 .db3 and MCAP), written here with rosbags'
writer: aligned depth passes through, depth with extrinsics is re-projected, colour encodings, clear errors."""

import json

import numpy as np
import pytest
from realsense_recordings import expected_depth, scene
from ros2_bags import write_bag

from deploy.cli import main
from drivers.camera.frames_dir import FramesRecording
from drivers.camera.realsense_convert import convert_recording, recording_kind
from drivers.camera.registry import open_camera
from drivers.camera.ros2_bag import Ros2BagCamera
from drivers.errors import RecordingError

N = 4


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_aligned_depth_converts_without_a_lost_pixel(capsys, tmp_path, storage):
    s = scene(N, depth_fx=50.0, color_fx=50.0, baseline_m=0.0)
    bag = write_bag(tmp_path / "bag", s, aligned=True, storage=storage)
    (file,) = bag.glob("*.db3" if storage == "sqlite3" else "*.mcap")
    for source in (bag, file):  # the bag folder or its one file
        assert recording_kind(source) == "ros2"
        out = tmp_path / f"frames-{source.name}"
        code, printed, err = run(capsys, "convert", source, "--out", out, "--json")
        assert code == 0, err
        summary = json.loads(printed)
        assert summary["frames"] == N and summary["source"] == "ros2"
        rec = FramesRecording(out)
        assert rec.intrinsics.fx == 50.0 and rec.intrinsics.width == 64 and not rec.simulated
        for k in range(N):
            frame = rec.frame(k)
            np.testing.assert_array_equal(frame.color, s.color[k])
            np.testing.assert_allclose(frame.depth_m, s.depth[k] * s.depth_units_m, atol=1e-6)
            assert frame.t == pytest.approx(k / 30, abs=1e-6)


def test_the_colour_lens_is_kept(tmp_path):
    lens = (-0.0553, 0.0667, -0.0007, 0.0006, -0.0212)  # realsense-ros writes a RealSense lens as plumb_bob
    bag = write_bag(tmp_path / "bag", scene(1), aligned=True, color_d=lens)
    convert_recording(bag, tmp_path / "frames")
    intrinsics = FramesRecording(tmp_path / "frames").intrinsics
    assert intrinsics.distortion == "brown_conrady" and intrinsics.coeffs == pytest.approx(lens)


def test_depth_with_extrinsics_is_reprojected(tmp_path):
    s = scene(2, width=96, height=72, depth_fx=50.0, color_fx=50.0, baseline_m=0.1)
    bag = write_bag(tmp_path / "bag", s, aligned=False, storage="mcap", color_encoding="bgr8")
    summary = convert_recording(bag, tmp_path / "frames")
    assert summary["frames"] == 2
    frame = FramesRecording(tmp_path / "frames").frame(1)
    np.testing.assert_array_equal(frame.color, s.color[1])  # bgr8 delivered as RGB
    np.testing.assert_allclose(frame.depth_m, expected_depth(s), atol=1e-3)


def test_replay_reads_a_bag_and_a_bag_without_depth_geometry_is_refused(tmp_path):
    s = scene(2, depth_fx=50.0, color_fx=50.0, baseline_m=0.0)
    bag = write_bag(tmp_path / "bag", s, aligned=True)
    with open_camera(f"replay:{bag}") as camera:
        assert camera.read().index == 0 and camera.read().index == 1
        with pytest.raises(RecordingError, match="end of ROS 2 bag"):
            camera.read()
    lagging = write_bag(tmp_path / "lag", s, aligned=True, depth_lag_ms=1000.0)  # no depth near any colour
    with Ros2BagCamera(lagging) as camera, pytest.raises(RecordingError, match="after 0 frames"):
        camera.read()
    with Ros2BagCamera(write_bag(tmp_path / "raw", s, aligned=False)) as camera:  # with the extrinsics it works
        assert camera.read().depth_m.shape == (48, 64)
    with pytest.raises(RecordingError, match="no aligned depth topic .* lacks extrinsics: record with "
                                             "align_depth.enable:=true"):
        Ros2BagCamera(write_bag(tmp_path / "bare", s, aligned=False, extrinsics=False)).connect()


def test_bags_that_cannot_be_converted(tmp_path):
    (tmp_path / "x.mcap").write_bytes(b"not a bag")
    with pytest.raises(RecordingError, match="cannot read ROS 2 bag"):
        convert_recording(tmp_path / "x.mcap", tmp_path / "out")
    with pytest.raises(RecordingError, match="not found"):
        Ros2BagCamera(tmp_path / "missing.mcap")
