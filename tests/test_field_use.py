"""Field use: the filter follows the camera, one TOML config for a run, the step lines, --verbose, --version,
--json on every command, and the rerun viewer (headless: saved to a file)."""

import json
import logging

import numpy as np
import pytest
import typer
from realsense_recordings import scene, write_db3
from rerun_files import entities
from ros2_bags import write_bag

from deploy.cli import app, main
from deploy.config import Config, filter_profile_for, load_config
from deploy.control.session import OpenRequest
from deploy.control.viewer import STEP_LOGGER, EpisodeView, RerunViewer
from deploy.geometry.types import Axis, JointType
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesWriter
from drivers.camera.realsense_convert import convert_recording

INTR = Intrinsics(32, 24, 30.0, 30.0, 15.5, 11.5)
SPARSE = {"profile": "sparse", "radius_m": pytest.approx(0.013), "eps": 1}


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def frame(i: int = 0) -> Frame:
    return Frame(i, 0.1 * i, np.full((24, 32, 3), 100, np.uint8), np.full((24, 32), 1.0, np.float32), INTR,
                 T_base_camera=np.eye(4))


def frames_recording(path, simulated: bool):
    with FramesWriter(path, INTR, camera="sim" if simulated else "d415", simulated=simulated) as writer:
        writer.write(frame())
    return path


def test_the_filter_follows_the_camera(tmp_path):
    assert filter_profile_for("sim") == "sim"
    assert filter_profile_for("d415") == filter_profile_for("d415:1234") == "sparse"  # no device needed
    assert filter_profile_for(f"replay:{frames_recording(tmp_path / 'sim', True)}") == "sim"
    assert filter_profile_for(f"replay:{frames_recording(tmp_path / 'real', False)}") == "sparse"
    db3 = write_db3(tmp_path / "s.db3", scene(2))
    assert filter_profile_for(f"replay:{db3}") == "sparse"
    convert_recording(db3, tmp_path / "converted")
    assert not FramesRecording(tmp_path / "converted").simulated
    assert filter_profile_for(f"replay:{tmp_path / 'converted'}") == "sparse"
    assert filter_profile_for(f"replay:{write_bag(tmp_path / 'ros', scene(2), aligned=True)}") == "sparse"
    (tmp_path / "real" / "truth.json").write_text("{}")  # an older simulated recording: meta.json says nothing
    assert filter_profile_for(f"replay:{tmp_path / 'real'}") == "sim"
    resolved = OpenRequest(task="drawer", camera="d415").config().filter.resolve()
    assert (resolved.radius_m, resolved.eps) == (pytest.approx(0.013), 1)  # the paper's real-camera setting
    assert OpenRequest(task="drawer").config().filter.profile == "sim"
    assert Config().filter.resolve().radius_m == 0.05  # no camera known: the simulation setting


def test_one_config_file_for_a_run_with_options_on_top(tmp_path):
    file = tmp_path / "run.toml"
    file.write_text('[filter]\nprofile = "sim"\n[opening]\ntarget_distance_m = 0.2\npull_speed_m_s = 0.05\n'
                    'timeout_s = 30\n[perception]\nobject_prompt = "dresser"\nbox_threshold = 0.4\n')
    request = OpenRequest(task="drawer", camera="d415", config_file=file,
                          overrides={"perception.box": (1.0, 2.0, 30.0, 20.0)})
    config = request.config()
    assert config.filter.profile == "sim"  # the file's choice beats the camera's default
    assert (config.opening.target_distance_m, config.opening.pull_speed_m_s, config.opening.timeout_s) == (0.2, 0.05,
                                                                                                           30.0)
    assert config.perception.object_prompt == "dresser" and config.perception.box == (1.0, 2.0, 30.0, 20.0)
    spec = request.rig_spec(config)
    assert spec.perception.box_threshold == 0.4 and spec.perception.box == (1.0, 2.0, 30.0, 20.0)
    assert OpenRequest(task="drawer", config_file=file, distance_m=0.25).config().opening.target_distance_m == 0.25
    assert load_config(file).filter.profile == "sim"


def test_open_options_reach_the_run(capsys, tmp_path):
    file = tmp_path / "run.toml"
    file.write_text('[filter]\nprofile = "sparse"\n[opening]\nmax_steps = 1\n')
    code, out, err = run(capsys, "open-door", "--dry-run", "--config", file, "--prompt", "cupboard door",
                         "--run-dir", tmp_path / "run", "--json")
    data = json.loads(out)
    assert code == 0 and data["filter"] == SPARSE and data["policy"] == "closed", err
    code, out, _ = run(capsys, "open-door", "--dry-run", "--config", file, "--filter", "sim", "--run-dir",
                       tmp_path / "run2", "--json")
    assert code == 0 and json.loads(out)["filter"] == {"profile": "sim", "radius_m": 0.05, "eps": 100}


def test_episode_view_logs_one_line_per_step(caplog, tmp_path):
    view = EpisodeView()
    axis = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0.0, 0.0, 1.0]), confidence=0.734)
    with caplog.at_level(logging.INFO, logger=STEP_LOGGER):
        view.axis(1.0, axis, 12.5)
        view.axis(2.0, axis, 24.0, "trajectory")
        view.close()
    assert [r.getMessage() for r in caplog.records] == [
        "step 0: opened 12.500 deg, axis revolute, confidence 0.73",
        "step 1: opened 24.000 deg, axis revolute from trajectory, confidence 0.73"]


def test_rerun_viewer_saves_the_camera_in_3d_the_axes_and_the_truth(tmp_path):
    viewer = RerunViewer(tmp_path / "view.rrd", spawn=False)
    view = EpisodeView(viewer)
    view.true_axis(Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0.0, 0.0])))
    for i in range(3):
        view.frame(0.1 * i, frame(i), np.ones((24, 32), bool), np.eye(4))
        view.axis(0.1 * i, Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0.1 * i, 0.0])), 0.05 * i)
    view.close()
    found = entities(tmp_path / "view.rrd")
    assert {"Pinhole:image_from_camera", "Pinhole:resolution"} <= found["/world/camera/image"]["components"]
    assert "Transform3D:translation" in found["/world/camera"]["components"]
    for name in ("color", "depth", "mask"):
        assert found[f"/world/camera/image/{name}"]["rows"] == 3
    assert found["/world/axis/estimated"]["rows"] == 3 and found["/world/axis/true"]["rows"] == 1
    assert found["/opening"]["rows"] == 3 and found["/world/gripper"]["rows"] == 3


def test_verbose_logs_info_and_version(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0 and out.startswith("axisloop ")
    run(capsys, "--verbose", "cameras", "list", "--json")
    logging.getLogger("deploy.test").debug("details of our own")
    logging.getLogger("urllib3").debug("details of a library")
    err = capsys.readouterr().err
    assert "details of our own" in err and "details of a library" not in err
    assert logging.getLogger().getEffectiveLevel() == logging.INFO
    run(capsys, "cameras", "list", "--json")
    logging.getLogger("deploy.test").info("quiet")
    assert "quiet" not in capsys.readouterr().err
    assert logging.getLogger(STEP_LOGGER).getEffectiveLevel() == logging.INFO  # step lines without --verbose


def _commands(group, prefix: str = ""):
    for name, command in group.commands.items():
        if hasattr(command, "commands"):
            yield from _commands(command, f"{prefix}{name} ")
        else:
            yield f"{prefix}{name}", command


def test_every_command_speaks_json_and_names_units():
    commands = dict(_commands(typer.main.get_command(app)))
    assert len(commands) >= 33
    missing = [name for name, command in commands.items()
               if not any("--json" in p.opts for p in command.params)]
    assert missing == []
    for name, command in commands.items():
        for param in command.params:
            if "--distance" in param.opts or "--angle" in param.opts:
                assert ("metres" in param.help or "(m)" in param.help) if "--distance" in param.opts else \
                    "degrees" in param.help, name
            assert "--scene" not in param.opts or param.hidden, name
            assert "--auto-joint" not in param.opts or param.hidden, name
            if "--yes" in param.opts:
                assert "-y" in param.opts, name
