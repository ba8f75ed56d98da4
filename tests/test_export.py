"""`deploy export REC --format tum|open3d|rrd` on a synthetic drawer recording (masks, camera pose, gripper
path): the files other tools read, read back with those tools' conventions (Open3D's own readers); a recording
marking when the gripper held exports only the held handle's path."""

import json
import shutil

import cv2
import numpy as np
import open3d as o3d
import pytest
from rerun_files import entities

from deploy.cli import main
from deploy.geometry.metrics import axis_angle_error_deg
from deploy.synthetic.sequence import synthetic_sequence, write_sequence
from drivers.camera.depth_noise import DepthNoise
from drivers.camera.frames_dir import FramesRecording

N = 6


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    seq = synthetic_sequence("drawer", np.random.default_rng(3), travel=0.10, n_frames=N, noise=DepthNoise.d415())
    path = tmp_path_factory.mktemp("export") / "drawer"
    write_sequence(seq, path)
    return path


def test_tum_layout(capsys, recording, tmp_path):
    out = tmp_path / "tum"
    code, printed, err = run(capsys, "export", recording, "--format", "tum", "--out", out, "--json")
    assert code == 0, err
    assert json.loads(printed)["files"] == ["rgb.txt", "depth.txt", "associations.txt", "groundtruth.txt", "tool.txt",
                                            "camera_intrinsic.json"]
    rec = FramesRecording(recording)
    rgb = [line.split() for line in (out / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    depth = [line.split() for line in (out / "depth.txt").read_text().splitlines() if not line.startswith("#")]
    assert len(rgb) == len(depth) == N and rgb[1] == [f"{rec.frame(1).t:.6f}", f"rgb/{rec.frame(1).t:.6f}.png"]
    image = cv2.imread(str(out / depth[2][1]), cv2.IMREAD_UNCHANGED)
    assert image.dtype == np.uint16
    np.testing.assert_allclose(image / 5000.0, rec.frame(2).depth_m, atol=1e-3)  # TUM: 5000 units per metre
    colour = cv2.cvtColor(cv2.imread(str(out / rgb[2][1])), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(colour, rec.frame(2).color)
    truth = np.loadtxt(out / "groundtruth.txt")
    assert truth.shape == (N, 8)
    np.testing.assert_allclose(truth[0, 1:4], rec.T_base_camera[:3, 3], atol=1e-6)
    code, printed, _ = run(capsys, "axis", "fit-trajectory", out / "tool.txt", "--json")  # the gripper's path
    assert code == 0 and json.loads(printed)["joint_type"] == "prismatic"
    code, _, err = run(capsys, "export", recording, "--format", "tum", "--out", out)
    assert code == 2 and "pass --overwrite" in err
    assert run(capsys, "export", recording, "--format", "tum", "--out", out, "--overwrite")[0] == 0


def test_open3d_layout_reads_with_open3d(capsys, recording, tmp_path):
    out = tmp_path / "o3d"
    code, _, err = run(capsys, "export", recording, "--format", "open3d", "--out", out)
    assert code == 0, err
    intr = FramesRecording(recording).intrinsics
    read = o3d.io.read_pinhole_camera_intrinsic(str(out / "camera_intrinsic.json"))
    assert (read.width, read.height) == (intr.width, intr.height)
    np.testing.assert_allclose(read.intrinsic_matrix, intr.K)
    trajectory = o3d.io.read_pinhole_camera_trajectory(str(out / "trajectory.log"))
    assert len(trajectory.parameters) == N
    np.testing.assert_allclose(np.linalg.inv(trajectory.parameters[0].extrinsic),
                               FramesRecording(recording).T_base_camera, atol=1e-6)
    depth = o3d.io.read_image(str(out / "depth" / "000003.png"))
    colour = o3d.io.read_image(str(out / "color" / "000003.png"))
    config = json.loads((out / "config.json").read_text())
    rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(colour, depth, depth_scale=config["depth_scale"],
                                                              convert_rgb_to_intensity=False)
    cloud = o3d.geometry.PointCloud.create_from_rgbd_image(rgbd, read)
    assert len(cloud.points) > 0.5 * intr.width * intr.height


def test_rrd_export_and_a_folder_that_is_not_an_export(capsys, recording, tmp_path):
    code, _, err = run(capsys, "export", recording, "--format", "rrd", "--out", tmp_path / "drawer.rrd")
    assert code == 0, err
    found = entities(tmp_path / "drawer.rrd")
    assert found["/world/camera/image/color"]["rows"] == N and found["/world/camera/image/mask"]["rows"] == N
    assert "Pinhole:image_from_camera" in found["/world/camera/image"]["components"]
    assert found["/world/gripper"]["rows"] == N
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    code, _, err = run(capsys, "export", recording, "--out", tmp_path / "mine", "--overwrite")
    assert code == 2 and "is not a tum export" in err and (tmp_path / "mine" / "notes.txt").exists()
    notes = tmp_path / "notes.rrd"  # not a rerun file: never replaced, even with --overwrite
    notes.write_text("my notes")
    code, _, err = run(capsys, "export", recording, "--format", "rrd", "--out", notes, "--overwrite")
    assert code == 2 and "is not an rrd export" in err and notes.read_text() == "my notes"
    assert run(capsys, "export", recording, "--format", "rrd", "--out", tmp_path / "drawer.rrd", "--overwrite")[0] == 0
    code, _, err = run(capsys, "export", recording, "--format", "rrd", "--out", tmp_path / "x.txt")
    assert code == 2 and "give --out NAME.rrd" in err


def test_tum_tool_txt_holds_only_the_held_handles_path(capsys, recording, tmp_path):
    """A recording that says when the gripper held the handle (`grasped`) exports only those frames' gripper poses
    to tool.txt: `axis fit-trajectory` reads the handle's path there, not the approach to it."""
    rec = tmp_path / "marked"
    shutil.copytree(recording, rec)
    lines = [json.loads(line) for line in (rec / "frames.jsonl").read_text().splitlines()]
    direction = np.array(json.loads((rec / "truth.json").read_text())["direction"])
    side = np.cross(direction, [0.0, 0.0, 1.0])
    for i, line in enumerate(lines):
        line["grasped"] = i >= 2
        if i < 2:  # the approach: from the side, toward where the grasp is
            pose = np.array(lines[2]["ee_pose"])
            pose[:3, 3] += (2 - i) * 0.08 * side / np.linalg.norm(side)
            line["ee_pose"] = pose.tolist()
    (rec / "frames.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    out = tmp_path / "tum"
    code, _, err = run(capsys, "export", rec, "--format", "tum", "--out", out)
    assert code == 0, err
    text = (out / "tool.txt").read_text()
    assert "# only the 4 frames marked grasped: 2 not holding the handle left out" in text
    tool = np.loadtxt(out / "tool.txt")
    np.testing.assert_allclose(tool[:, 0], [line["t"] for line in lines[2:]], atol=1e-6)
    code, printed, _ = run(capsys, "axis", "fit-trajectory", out / "tool.txt", "--json")
    fitted = json.loads(printed)
    assert code == 0 and fitted["joint_type"] == "prismatic"
    assert axis_angle_error_deg(direction, fitted["direction"]) < 5.0


def test_a_refused_export_names_its_format_with_the_right_article(capsys, recording, tmp_path):
    """"an open3d export", not "a open3d export"."""
    out = tmp_path / "o3d"
    assert run(capsys, "export", recording, "--format", "open3d", "--out", out)[0] == 0
    code, _, err = run(capsys, "export", recording, "--format", "open3d", "--out", out)
    assert code == 2 and f"--out {out}: an open3d export is already there: pass --overwrite" in " ".join(err.split())
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    code, _, err = run(capsys, "export", recording, "--format", "open3d", "--out", tmp_path / "mine")
    assert code == 2 and "is not an open3d export" in " ".join(err.split())


def test_depth_beyond_a_formats_range_is_no_depth_not_a_wrong_depth(capsys, recording, tmp_path):
    """A 20 m plane is 100000 TUM units: written as 65535 it read back as 13.1 m; now 0 (no depth), counted."""
    far = tmp_path / "far"
    shutil.copytree(recording, far)
    depth = far / "depth" / "000001.png"
    units = cv2.imread(str(depth), cv2.IMREAD_UNCHANGED)
    units[:2, :3] = 20000  # 20 m at the recording's 1 mm per unit
    cv2.imwrite(str(depth), units)
    for fmt, per_m in (("tum", 5000.0), ("open3d", 1000.0)):
        code, printed, err = run(capsys, "export", far, "--format", fmt, "--out", tmp_path / fmt, "--json")
        assert code == 0, err
        data = json.loads(printed)
        name = sorted((tmp_path / fmt / "depth").iterdir())[1]
        image = cv2.imread(str(name), cv2.IMREAD_UNCHANGED)
        if fmt == "tum":
            assert data["depth_out_of_range_px"] == 6 and (image[:2, :3] == 0).all()
        else:  # 20 m fits Open3D's millimetres
            assert data["depth_out_of_range_px"] == 0 and np.allclose(image[:2, :3] / per_m, 20.0)
