"""Every bad input ends with one clear line and exit code 2 (the traceback only with `deploy --verbose`, a JSON
error object with --json); nothing is replaced without --overwrite; a damaged replay stops with the frame named
after flushing what was written; Ctrl-C and SIGTERM stop with a line, the motors disabled and the run folder
complete up to then."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_run import one_line, run, small_recording
from realsense_recordings import scene, write_db3

from deploy.control.state import StopReason
from drivers.arm.robot_config import PANDA_SIM_CONFIG
from drivers.camera.frames_dir import FramesRecording

ROOT = Path(__file__).resolve().parents[1]
PANDA = PANDA_SIM_CONFIG


def _robot(tmp_path: Path, old: str, new: str) -> Path:
    text = PANDA.read_text()
    assert old in text
    path = tmp_path / "robot.toml"
    path.write_text(text.replace(old, new))
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A small simulated recording (6 frames, 160x120)."""
    return small_recording(tmp_path_factory.mktemp("rec") / "rec")


# --- one line, exit code 2 ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("args", "words"), [
    (("open-drawer", "--distance", "-0.3"), "invalid value for --distance: -0.3: input should be greater than 0"),
    (("open-drawer", "--seed", "-1"), "'--seed'"),
    (("open-door", "--angle", "720"), "invalid value for --angle: 720.0: input should be less than or equal to 170"),
    (("bench", "open", "--distance", "50"), "invalid value for --distance: 50: input should be less than or equal"),
    (("bench", "open", "--task", "door", "--distance", "0.45"), "--distance is for the other task, not --task door"),
    (("bench", "open", "--segmenter", "classical"), "--segmenter classical needs the object's box on each scene's"),
    (("bench", "open", "--task", "drawer", "--distance", "0.3", "--target", "0.2"),
     "--target 0.2 with --distance: --target is the old name of --distance and both set the target: give --distance"),
    (("bench", "open", "--task", "door", "--angle", "45", "--target", "0.3"), "--target 0.3 with --angle: --target is"),
    (("bench", "axis", "--scenes", "paths", "--sequences", "50"), "--sequences 50 with --scenes paths: the paths set"),
    (("bench", "open", "--episodes", "1000000"), "'--episodes'"),
    (("arm", "jog", "--joint", "panda_joint1", "--delta", "nan", "--yes"), "'--delta': nan is not a finite number"),
    (("arm", "move", "--pose", "0.4", "0", "inf", "0", "0", "0"), "'--pose': inf is not a finite number"),
    (("arm", "scan", "--first-id", "0"), "'--first-id'"),
    (("arm", "scan", "--first-id", "5", "--last-id", "2"), "--last-id 2 is below --first-id 5"),
    (("arm", "enable", "--hold", "-1", "--yes"), "'--hold'"),
    (("sim", "record", "--fps", "0", "--out", "x"), "'--fps': 0 is not above 0"),
    (("sim", "show", "--seed", "-2"), "'--seed'"),
    (("record", "--camera", "sim", "--width", "0", "--out", "x", "--frames", "1"), "'--width'"),
    (("record", "--camera", "sim", "--width", "-5", "--height", "3", "--out", "x", "--frames", "1"), "'--width'"),
    (("record", "--camera", "sim", "--out", "x", "--seconds", "0"), "'--seconds'"),
    (("convert", "a.db3", "--out", "x", "--depth-scale", "-1"), "'--depth-scale'"),
    (("bench", "open", "--episodes", "0"), "'--episodes'"),
    (("bench", "axis", "--sequences", "0"), "'--sequences'"),
    (("calibrate", "check", "--max-age-days", "nan"), "'--max-age-days'"),
    (("axis", "demo", "--seed", "-1"), "'--seed'"),
    (("arm", "jog", "--joint", "panda_joint1", "--delt", "3"), "No such option: --delt"),
    (("open-drawer", "--calibration", "garbage.yaml"), "--calibration garbage.yaml is for a real camera"),
    (("arm", "status", "--robot", "/nonexistent.toml"), "robot config /nonexistent.toml not found"),
])
def test_bad_options_are_one_line_with_exit_code_2(capsys, tmp_path, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *args)
    assert code == 2 and words in one_line(err)
    assert not (tmp_path / "x").exists()


def test_a_path_that_cannot_be_written_is_one_line(capsys, tmp_path):
    (tmp_path / "file").write_text("")
    code, _, err = run(capsys, "record", "--camera", "sim", "--frames", "1", "--out", tmp_path / "file" / "rec")
    assert code == 2 and f"{tmp_path / 'file' / 'rec'}: Not a directory: check the path" in one_line(err)


def test_verbose_adds_the_traceback_and_json_adds_the_error_object(capsys):
    code, out, err = run(capsys, "--verbose", "arm", "jog", "--joint", "elbow", "--delta", "0.1", "--yes", "--json")
    assert code == 2 and "Traceback" in err and "error: joint 'elbow' is not one of" in err
    data = json.loads(out)
    assert data["kind"] == "ArmError" and data["exit_code"] == 2 and data["error"].startswith("joint 'elbow'")
    assert [m["status"] for m in data["motors"]] == ["disabled"] * 8  # probed, never enabled


def test_a_bug_is_one_line_naming_the_verbose_flag(capsys, monkeypatch):
    def broken(_arm):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr("deploy.arm_bringup.status", broken)
    code, _, err = run(capsys, "arm", "status")
    assert code == 1 and "internal error (ZeroDivisionError: float division by zero)" in one_line(err)
    assert "deploy --verbose arm status" in err


@pytest.mark.parametrize(("old", "new", "words"), [
    ("workspace_min = [-0.9, -0.9, 0.02]", "workspace_min = [nan, nan, nan]",
     "workspace_min.0: Input should be a finite number"),
    ("feedback_timeout_s = 0.02", "feedback_timeout_s = inf", "watchdog.feedback_timeout_s: Input should be a finite"),
    # absurd but finite: the box no longer holds the tool above the table, the acceleration check never trips
    ("workspace_min = [-0.9, -0.9, 0.02]", "workspace_min = [-1e9, -1e9, -1e9]",
     "workspace_min.0: Input should be greater than or equal to -3"),
    ("a_max = 15.0", "a_max = 1e300", "joints.0.a_max: Input should be less than or equal to 200"),
    ("tau_max = 87.0", "tau_max = 1e300", "joints.0.tau_max: Value error, tau_max 1e+300 N m is above the "
     "DM10010L's TMAX 200 N m"),
])
def test_a_robot_config_that_switches_a_safety_check_off_is_refused(capsys, tmp_path, old, new, words):
    robot = _robot(tmp_path, old, new)
    code, _, err = run(capsys, "arm", "move", "--pose", "0.4", "0", "0.0", "180", "0", "0", "--arm", "sim-can",
                       "--yes", "--robot", robot)
    assert code == 2 and f"robot config {robot}: {words}" in one_line(err)


@pytest.mark.parametrize("target", ["robot", "recording", "config"])
def test_random_bytes_are_one_line(capsys, tmp_path, recording, target):
    junk = bytes(range(256)) * 4
    if target == "robot":
        (tmp_path / "robot.toml").write_bytes(junk)
        args, words = ("arm", "status", "--robot", tmp_path / "robot.toml"), "is not UTF-8 text"
    elif target == "config":
        (tmp_path / "run.toml").write_bytes(junk)
        args, words = ("axis", "estimate", recording, "--config", tmp_path / "run.toml"), "is not UTF-8 text"
    else:
        rec = tmp_path / "rec"
        rec.mkdir()
        (rec / "meta.json").write_bytes((recording / "meta.json").read_bytes())
        (rec / "frames.jsonl").write_bytes(junk)
        args, words = ("axis", "estimate", rec), "frames.jsonl is not UTF-8 text"
    code, _, err = run(capsys, *args)
    assert code == 2 and words in one_line(err)


# --- nothing replaced without asking -------------------------------------------------------------------------------


def _files(path: Path) -> dict[str, bytes]:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("command", ["record", "sim-record", "convert", "track"])
def test_an_existing_recording_is_refused_then_replaced_whole_with_overwrite(capsys, tmp_path, recording, command):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("meta.json", "frames.jsonl"):
        (out / name).write_bytes((recording / name).read_bytes())
    (out / "truth.json").write_text("{}")  # the old recording's ground truth must not survive
    before = _files(out)
    args = {"record": ("record", "--camera", f"replay:{recording}", "--frames", "2"),
            "sim-record": ("sim", "record", "--fps", "2"),
            "convert": ("convert", write_db3(tmp_path / "s.db3", scene(3))),
            "track": ("track", recording, "--segmenter", "classical", "--box", "40", "30", "120", "90")}[command]
    code, _, err = run(capsys, *args, "--out", out)
    assert code == 2 and "a recording is already there: pass --overwrite" in one_line(err)
    assert _files(out) == before
    code, _, err = run(capsys, *args, "--out", out, "--overwrite")
    assert code == 0, err
    if command == "sim-record":  # it writes a truth.json of its own
        assert json.loads((out / "truth.json").read_text())
    else:
        assert not (out / "truth.json").exists()
        assert len(FramesRecording(out)) == {"record": 2, "convert": 3, "track": 6}[command]


def test_a_folder_that_is_not_a_recording_is_never_removed(capsys, tmp_path):
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "todo.txt").write_text("keep me")
    code, _, err = run(capsys, "record", "--camera", "sim", "--frames", "1", "--out", tmp_path / "notes",
                       "--overwrite")
    assert code == 2 and "holds no recording or run folder" in one_line(err)
    assert (tmp_path / "notes" / "todo.txt").read_text() == "keep me"


def test_an_existing_run_folder_is_refused_then_replaced_whole(capsys, tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "steps.json").write_text("{}")
    (run_dir / "episode.rrd").write_text("old")
    code, _, err = run(capsys, "open-drawer", "--dry-run", "--run-dir", run_dir)
    assert code == 2 and "--run-dir" in one_line(err) and _files(run_dir) == {"episode.rrd": b"old",
                                                                              "steps.json": b"{}"}
    code, _, err = run(capsys, "open-drawer", "--dry-run", "--run-dir", run_dir, "--overwrite", "--json")
    assert code == 0, err
    assert not (run_dir / "episode.rrd").exists() and json.loads((run_dir / "steps.json").read_text())["result"]


def test_a_damaged_replay_stops_naming_the_frame_and_keeps_what_was_written(capsys, tmp_path, recording):
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    for p in recording.rglob("*"):
        if p.is_file():
            (damaged / p.relative_to(recording)).parent.mkdir(parents=True, exist_ok=True)
            (damaged / p.relative_to(recording)).write_bytes(p.read_bytes())
    (damaged / "depth" / "000004.png").write_bytes(b"")
    code, out, err = run(capsys, "record", "--camera", f"replay:{damaged}", "--out", tmp_path / "out", "--frames",
                         "100")
    line = one_line(err)
    assert code == 2 and "frame 4 is damaged" in line and "depth/000004.png is not a readable PNG" in line
    assert "the 4 frames recorded so far are kept" in line and "wrote" not in out
    assert len(FramesRecording(tmp_path / "out")) == 4


# --- faults of the simulated CAN arm on every command that takes it ------------------------------------------------


def test_record_with_the_simulated_can_arm_takes_sim_faults(capsys, tmp_path):
    """SECONDS counts the recording's time (the arm is only read): a bus-off 0.1 s in stops the recording with the
    bus's line, keeping the frames before it; a fault of a motor not in the config, or without sim-can, is refused."""
    args = ("record", "--camera", "sim", "--arm", "sim-can", "--frames", "10", "--width", "160", "--height", "120")
    code, _, err = run(capsys, *args, "--out", tmp_path / "a", "--sim-fault", "bus-off@0.1")
    assert code == 2 and "went bus-off (error frame)" in err.splitlines()[-1] and "Traceback" not in err
    assert 1 <= len(FramesRecording(tmp_path / "a")) < 10
    code, _, err = run(capsys, *args, "--out", tmp_path / "b", "--sim-fault", "silent:panda_joint3")
    assert code == 2 and "motor panda_joint3 (CAN id 3, master 0x13) did not answer" in err.splitlines()[-1]
    code, _, err = run(capsys, *args, "--out", tmp_path / "c", "--sim-fault", "silent:elbow")
    assert code == 2 and "--sim-fault silent:elbow: no motor 'elbow'" in err.splitlines()[-1]
    code, _, err = run(capsys, *args[:3], *args[5:], "--out", tmp_path / "d", "--sim-fault", "bus-off")
    assert code == 2 and "use it with --arm sim-can, not --arm none" in one_line(err)
    assert not (tmp_path / "d").exists()


# --- Ctrl-C and SIGTERM ----------------------------------------------------------------------------------------


def _deploy(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "deploy", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))


def _wait_for(condition, process: subprocess.Popen, timeout_s: float = 120.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)


@pytest.mark.parametrize(("sig", "arm", "motors"), [
    (signal.SIGINT, "sim", "arm stopped"), (signal.SIGTERM, "sim-can", "all 8 motors disabled")])
def test_a_signal_during_an_opening_keeps_the_run_folder_complete(tmp_path, sig, arm, motors):
    run_dir = tmp_path / "run"
    frames = run_dir / "frames" / "frames.jsonl"
    process = _deploy("open-drawer", "--world", "box", "--arm", arm, "--seed", "1", "--run-dir", str(run_dir))
    _wait_for(lambda: frames.exists() and frames.read_text().count("\n") >= 3, process)
    process.send_signal(sig)
    out, err = process.communicate(timeout=120)
    name = "SIGINT (Ctrl-C)" if sig == signal.SIGINT else "SIGTERM"
    assert process.returncode == 128 + sig
    assert f"error: stopped by {name}; {motors}; the run folder {run_dir} holds the frames, steps.json and " \
           "report.png up to here" in err and "Traceback" not in err
    steps = json.loads((run_dir / "steps.json").read_text())
    assert steps["result"]["stop_reason"] == StopReason.INTERRUPTED
    assert steps["result"]["message"] == f"stopped by {name}"
    assert (run_dir / "report.png").stat().st_size > 0 and len(FramesRecording(run_dir / "frames")) >= 3


def test_ctrl_c_while_the_arm_holds_disables_every_motor_and_says_so():
    process = _deploy("arm", "enable", "--yes", "--hold", "60")
    assert "enabled; holding" in process.stdout.readline()
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130 and "error: stopped by SIGINT (Ctrl-C); all 8 motors disabled" in err


def test_every_test_the_fault_matrix_names_exists():
    text = (ROOT / "docs" / "reliability.md").read_text()
    matrix = text.split("## Fault matrix", 1)[1].split("\n## ", 1)[0]
    current_file = None
    names = []
    for token in re.findall(r"`((?:tests/)?test_\w+\.py)?(?:::(\w+))?(?:\[[^\]]*\])?`", matrix):
        file, test = token
        current_file = file or current_file
        if test:
            names.append((current_file, test))
    assert len(names) > 30
    for file, test in names:
        path = ROOT / "tests" / Path(file).name
        assert path.is_file(), file
        assert re.search(rf"^def {test}\(", path.read_text(), re.M), f"{file}::{test}"


def test_bench_open_names_every_missing_model_before_any_episode(capsys, monkeypatch):
    """No weights: one line listing the detector and the tracker with their fetch commands, before any episode
    (bench open has no --detector/--tracker, so no "pass a local directory")."""
    from deploy.errors import ModelError
    from deploy.perception import models

    def not_cached(source):
        raise ModelError(f"model {source} is not in the Hugging Face cache")

    monkeypatch.setattr(models, "resolve_checkpoint", not_cached)
    monkeypatch.setattr("deploy.bench.open.simulate_episode", lambda **job: pytest.fail("an episode ran"))
    code, _, err = run(capsys, "bench", "open", "--segmenter", "gdino-sam2", "--episodes", "2")
    assert code == 2 and one_line(err) == (
        "error: --segmenter gdino-sam2 needs model weights this machine does not have: detector "
        "IDEA-Research/grounding-dino-tiny (fetch it with `hf download IDEA-Research/grounding-dino-tiny`), tracker "
        "facebook/sam2.1-hiera-tiny (fetch it with `hf download facebook/sam2.1-hiera-tiny`); fetch them, or use "
        "--segmenter rgbd (no weights)")


def test_bench_open_keeps_the_old_target_option_alone():
    """--target alone still sets the target (old name of --distance / --angle)."""
    from deploy.commands.bench import _bench_target
    from deploy.commands.options import Task

    assert _bench_target(Task.drawer, None, None, 0.2, None) == 0.2
    assert _bench_target(Task.door, None, None, 30.0, None) == 30.0
    assert _bench_target(Task.door, None, 50.0, None, None) == 50.0
