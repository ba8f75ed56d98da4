"""Field use: the filter follows the camera, one TOML config for a run, the step lines, --verbose, --version,
--json on every command, and the rerun viewer (headless: saved to a file)."""

import json
import logging
import shutil

import numpy as np
import pytest
import typer
from realsense_recordings import scene, write_db3
from rerun_files import entities
from ros2_bags import write_bag

from deploy.cli import app, main
from deploy.config import Config, filter_profile_for, load_config
from deploy.control.session import OpenRequest
from deploy.control.view import STEP_LOGGER, EpisodeView
from deploy.geometry.types import Axis, JointType
from deploy.report.viewer import RerunViewer
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
    code, out, err = run(capsys, "open-door", "--world", "box", "--dry-run", "--config", file, "--prompt",
                         "cupboard door", "--run-dir", tmp_path / "run", "--json")
    data = json.loads(out)
    assert code == 0 and data["filter"] == SPARSE and data["policy"] == "closed", err
    code, out, _ = run(capsys, "open-door", "--world", "box", "--dry-run", "--config", file, "--filter", "sim",
                       "--run-dir", tmp_path / "run2", "--json")
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
    for entity, component in (("image/color", "EncodedImage:blob"), ("depth/image", "EncodedDepthImage:blob"),
                              ("image/mask", "LineStrips2D:strips")):  # compressed colour, depth as depth, outline
        assert found[f"/world/camera/{entity}"]["rows"] == 3 and component in found[f"/world/camera/{entity}"][
            "components"]
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


# --- issue 18, remaining gaps ------------------------------------------------------------------------------


def test_step_lines_are_one_line_each_whatever_the_width(capsys):
    from deploy.commands.output import configure_logging

    axis = Axis(JointType.PRISMATIC, np.zeros(3), np.array([1.0, 0.0, 0.0]), confidence=0.5)
    source = "prior (" + "vision below its confidence threshold, " * 4 + "trajectory not yet moved far enough)"
    for verbose in (False, True):
        configure_logging(verbose)
        EpisodeView().axis(1.0, axis, 0.1234, source)
        lines = capsys.readouterr().err.splitlines()
        assert len(lines) == 1 and len(lines[0]) > 150, lines  # not wrapped at 80 columns when not a terminal
        assert lines[0].endswith(f"step 0: opened 0.123 m, axis prismatic from {source}, confidence 0.50")
        assert lines[0] == lines[0].rstrip()  # no padding to the console's width
    configure_logging(False)


def test_rows_print_nested_values_readably_and_small_values_with_their_digits(capsys):
    """A dict as "key value, ...", not a Python repr; a hinge error of 4.2 mm in metres keeps two significant
    digits (0.0042, not 0.004); None is "-", an empty dict "none"."""
    from deploy.commands.output import print_rows

    print_rows("t", {"calibration_error": {"translation_mm": 5.0, "rotation_deg": 0.5},
                     "axis_position_error_m_median": 0.0042, "mean_opened_m": 0.31234, "failures": {},
                     "failed_seeds": {"blocked": [3, 5]}, "frame_ms_median": None})
    out = capsys.readouterr().out
    assert "translation_mm 5.000, rotation_deg 0.500" in out and "{" not in out
    assert "0.0042" in out and "0.312 " in out and "blocked [3, 5]" in out and "none" in out


def test_progress_lines_when_stderr_is_not_a_terminal(capsys):
    from deploy.commands.output import LineBar, progress_bar

    bar = LineBar("tracking rec", every_s=0.0)
    for i in range(1, 4):
        bar.counts(i, 3)
    bar.describe("re-detecting")
    bar.finish()
    assert capsys.readouterr().err.splitlines() == [
        "tracking rec: 1/3", "tracking rec: 2/3", "tracking rec: 3/3", "tracking rec: re-detecting"]
    clock = iter([0.0, 0.5, 1.0, 2.5, 3.0, 3.1])
    bar = LineBar("record", every_s=2.0, clock=lambda: next(clock))
    for _ in range(4):
        bar.advance()
    bar.finish()  # the last count, since a count line was printed
    assert capsys.readouterr().err.splitlines() == ["record: 3", "record: 4"]
    with progress_bar("quick", 10) as bar:  # a short run prints nothing
        bar.completed(10)
    assert capsys.readouterr().err == ""


def test_verbose_logs_what_a_field_user_needs(capsys, tmp_path):
    code, out, err = run(capsys, "--verbose", "open-drawer", "--world", "box", "--dry-run", "--seed", "1", "--run-dir",
                         tmp_path / "r", "--json")
    assert code == 0, err
    for text in ("run config: filter sim (radius 0.05 m, eps 100); estimator screw-grip", "devices: camera sim",
                 "camera pose: simulated calibration", "segmenter", "found the object", "box (",
                 "handle found: centre", "grasp plan (dry run): grasp at"):
        assert text in err, text
    assert all(len(line) < 400 for line in err.splitlines())  # one record per line (plain, not a terminal)


def test_run_folder_keeps_the_resolved_config(capsys, tmp_path):
    file = tmp_path / "run.toml"
    file.write_text('[filter]\nradius_m = 0.04\n[opening]\nmax_steps = 2\ntimeout_s = 30\n')
    code, out, _ = run(capsys, "open-door", "--world", "box", "--dry-run", "--config", file, "--prompt", "cupboard",
                       "--run-dir", tmp_path / "run", "--json")
    assert code == 0
    kept = json.loads((tmp_path / "run" / "config.json").read_text())
    assert set(kept) == {"filter", "geometry", "estimator", "opening", "perception", "filter_used", "acted_with",
                         "scene"}
    assert kept["scene"]["world"] == "box" and kept["scene"]["pointer"]["source"] == "simulated user"
    assert kept["perception"]["point"] == [kept["scene"]["pointer"]["u"], kept["scene"]["pointer"]["v"]]
    assert kept["acted_with"] == {"estimator": "screw-grip", "fusion": "force"}
    assert kept["filter"] == {"profile": "sim", "radius_m": 0.04, "eps": None}  # the camera chose the profile
    assert kept["filter_used"] == {"radius_m": 0.04, "eps": 100} == {k: json.loads(out)["filter"][k]
                                                                    for k in ("radius_m", "eps")}
    assert kept["opening"]["task"] == "door" and kept["opening"]["max_steps"] == 2
    assert kept["perception"]["object_prompt"] == "cupboard"
    assert Config.model_validate({k: v for k, v in kept.items()
                                  if k not in ("filter_used", "acted_with", "scene")}).opening.timeout_s == 30
    code, _, _ = run(capsys, "open-door", "--world", "box", "--dry-run", "--policy", "paper", "--run-dir",
                     tmp_path / "paper")
    kept = json.loads((tmp_path / "paper" / "config.json").read_text())
    assert code == 0 and kept["acted_with"] == {"estimator": "paper-obb", "fusion": "vision"}
    assert kept["estimator"]["name"] == "screw-grip"  # the config's, which the paper's policy does not act with


def test_units_in_json_keys(capsys, tmp_path):
    axis = Axis(JointType.REVOLUTE, np.zeros(3), np.array([0.0, 0.0, 1.0]), radius_m=0.4)
    assert axis.to_dict()["radius_m"] == 0.4 and "radius" not in axis.to_dict()
    code, out, _ = run(capsys, "arm", "status", "--json")
    joints = json.loads(out)["joint_positions_rad"]
    assert code == 0 and len(joints) == 7 and all(isinstance(v, float) for v in joints.values())


def test_sim_can_arm_is_virtual_whatever_the_robot_config_says():
    from drivers.arm.robot_config import load_robot_config
    from sim_fallback.devices import sim_can_arm

    config = load_robot_config("damiao_6dof")
    assert config.can.interface == "socketcan" and config.can.channel == "can0"  # a real adapter's
    arm, motors = sim_can_arm(config)
    try:
        assert arm.bus.interface == "virtual" and arm.bus.channel.startswith("sim-can0-")
    finally:
        arm.disconnect()
        motors.close()


def test_help_texts_show_brackets_and_box_metavar(capsys):
    code, out, _ = run(capsys, "open-drawer", "--help")
    flat = " ".join(out.replace("│", " ").split())  # rich's panel borders and line breaks out
    assert "[filter] (profile, radius_m, eps) [geometry] [estimator] [opening]" in flat
    assert "[perception] (prompts" in flat and "(see Configuration in docs/quickstart.md)" in flat
    _, out, _ = run(capsys, "track", "--help")
    assert "X0 Y0 X1 Y1" in out and "<float" not in out


def test_views_of_a_recording_never_write_into_it(capsys, tmp_path, monkeypatch):
    from pathlib import Path

    from deploy.commands.output import view_file

    rec = tmp_path / "rec"
    with FramesWriter(rec, INTR, camera="sim", simulated=True) as writer:
        for i in range(2):
            writer.write(frame(i), mask=np.ones((24, 32), bool))
    before = sorted(p.name for p in rec.iterdir())
    assert view_file(rec, None, "axis") == Path("runs") / "rec-axis.rrd"
    assert view_file(rec, tmp_path / "mine.rrd", "track") == tmp_path / "mine.rrd"
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "axis", "estimate", rec, "--view", "--json")
    assert code == 1 and json.loads(out)["rrd"] == str(Path("runs") / "rec-axis.rrd"), err  # 2 frames: no axis
    assert (tmp_path / "runs" / "rec-axis.rrd").is_file() and sorted(p.name for p in rec.iterdir()) == before
    code, out, _ = run(capsys, "axis", "estimate", rec, "--rrd", tmp_path / "elsewhere.rrd", "--json")
    assert json.loads(out)["rrd"] == str(tmp_path / "elsewhere.rrd") and (tmp_path / "elsewhere.rrd").is_file()
    first = (tmp_path / "runs" / "rec-axis.rrd").read_bytes()  # a second view never replaces the first
    code, out, _ = run(capsys, "axis", "estimate", rec, "--view", "--json")
    assert json.loads(out)["rrd"] == str(Path("runs") / "rec-axis-2.rrd")
    assert (tmp_path / "runs" / "rec-axis.rrd").read_bytes() == first
    run_frames = tmp_path / "drawer-1" / "frames"  # a run's recording is named by its run folder, not "frames"
    shutil.copytree(rec, run_frames)
    (run_frames.parent / "steps.json").write_text("{}")
    assert view_file(run_frames, None, "axis") == Path("runs") / "drawer-1-axis.rrd"


def _eye_in_hand_file(path, T_camera):
    from calibration.board import BoardConfig
    from calibration.store import HandEyeRecord, save_hand_eye

    return save_hand_eye(HandEyeRecord(
        camera_serial="replay", robot_id="panda", setup="eye-in-hand", method="park", T_camera=T_camera,
        T_board=np.eye(4), tool_frame="panda_grasptarget", intrinsics=INTR, distortion=np.zeros(5),
        reprojection_px=0.3, spread_mm=1.0, spread_deg=0.3, samples=12, board=BoardConfig()), path=path)


def test_record_with_a_calibration_places_an_eye_in_hand_camera(capsys, tmp_path):
    rec = frames_recording(tmp_path / "rec", simulated=False)
    T_camera = np.eye(4)
    T_camera[:3, 3] = [0.05, 0.0, 0.04]
    calibration = _eye_in_hand_file(tmp_path / "handeye.yaml", T_camera)
    code, out, err = run(capsys, "--verbose", "record", "--camera", f"replay:{rec}", "--arm", "ideal", "--robot",
                         "panda_sim", "--calibration", calibration, "--out", tmp_path / "out", "--frames", 1, "--json")
    assert code == 0 and json.loads(out)["arm"], err
    assert f"hand-eye calibration {calibration} (eye-in-hand" in err  # --verbose names the file used
    recorded = FramesRecording(tmp_path / "out")
    tool = np.asarray(recorded.records[0]["ee_pose"])
    np.testing.assert_allclose(recorded.T_base_camera, tool @ T_camera, atol=1e-9)
    code, _, err = run(capsys, "record", "--camera", "sim", "--arm", "sim", "--calibration", calibration, "--out",
                       tmp_path / "out2", "--frames", 1)
    assert code == 2 and "--calibration" in err and "simulated camera" in err


def test_a_moving_camera_keeps_its_pose_per_frame(tmp_path):
    """drivers.camera.record with an eye-in-hand camera (posed as the rig poses it, from the arm's tool pose at
    each frame): each frame's pose is kept with it."""
    from drivers.camera.base import Camera
    from drivers.camera.posed import PosedCamera
    from drivers.camera.record import record

    class Replay(Camera):
        intrinsics = INTR

        def __init__(self):
            self.i = 0

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return None

        def connect(self):
            return None

        def disconnect(self):
            return None

        def read(self, timeout_s=2.0):
            self.i += 1
            return frame(self.i - 1)

    tools = [np.eye(4) + np.pad(np.array([[0.0, 0.0, 0.1 * i]]).T, ((0, 1), (3, 0))) for i in range(5)]
    offset = np.eye(4)
    offset[2, 3] = 0.03
    replay = Replay()
    tool_now = lambda: tools[replay.i - 1]  # noqa: E731  (the arm's tool pose when the frame was read)
    camera = PosedCamera(replay, lambda: tool_now() @ offset, override=True)  # Replay's frames carry an identity
    summary = record(camera, tmp_path / "rec", frames=3, arm=lambda: (np.zeros(7), tool_now()))
    recording = FramesRecording(tmp_path / "rec")
    assert summary["frames"] == 3 and recording.T_base_camera[2, 3] == pytest.approx(0.03)
    assert "T_base_camera" not in recording.records[0] and "T_base_camera" in recording.records[1]
    for i in range(3):
        assert recording.frame(i).T_base_camera[2, 3] == pytest.approx(0.03 + 0.1 * i)
        np.testing.assert_allclose(recording.frame(i).T_base_camera, np.asarray(recording.records[i]["ee_pose"])
                                   @ offset)


def test_sim_record_shows_its_phases_when_piped(capsys, tmp_path):
    code, _, err = run(capsys, "sim", "record", "--world", "box", "--task", "drawer", "--fps", "2", "--out",
                       tmp_path / "rec")
    assert code == 0
    shown = [line.split(": ", 1)[1] for line in err.splitlines() if line.startswith("sim record drawer (seed 0): ")]
    assert [s for s in shown if not s.isdigit()] == ["grasping the handle", "opening along the true axis",
                                                      "holding"], err  # and frame counts every 2 s between them
