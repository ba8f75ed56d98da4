"""The `deploy` command line end to end, on files and recordings the tests make themselves."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from rerun_files import entities
from scipy.spatial.transform import Rotation

from deploy.cli import main
from deploy.control.state import StopReason
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.synthetic.sequence import synthetic_sequence, write_sequence
from drivers.arm.robot_config import PANDA_SIM_CONFIG
from drivers.camera.depth_noise import DepthNoise


def run(capsys, *args):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_help_lists_every_group(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    for group in ("axis", "sim", "bench"):
        assert group in out


@pytest.mark.parametrize(
    "command",
    [("axis", "fit-trajectory"), ("axis", "estimate"), ("axis", "demo"), ("sim", "show"), ("sim", "record"),
     ("open-drawer",), ("open-door",), ("open",), ("bench", "open"),
     ("bench", "axis"), ("bench", "sim")],
)
def test_every_command_has_help_with_an_example(capsys, command):
    code, out, _ = run(capsys, *command, "--help")
    assert code == 0
    assert "Example" in out


def test_defaults_written_in_the_help_text_are_shown(capsys):
    """Square brackets are Rich markup: an unescaped "[default: ...]" would vanish from the help."""
    code, out, _ = run(capsys, "open-drawer", "--help")
    assert code == 0
    assert "[default:" in out and "runs/TASK-TIME]" in out


def test_fit_trajectory_json_on_an_arc(capsys, tmp_path):
    angles = np.radians(np.linspace(0, 40, 25))
    pts = np.c_[0.5 + 0.4 * np.cos(angles), 0.1 + 0.4 * np.sin(angles), np.full_like(angles, 0.7)]
    path = tmp_path / "arc.txt"
    path.write_text("# x y z\n" + "\n".join(", ".join(f"{v:.6f}" for v in p) for p in pts) + "\n")
    code, out, _ = run(capsys, "axis", "fit-trajectory", str(path), "--json")
    assert code == 0
    data = json.loads(out)
    assert set(data) >= {"joint_type", "origin", "direction", "radius_m", "residual_m", "n_samples"}
    assert data["joint_type"] == "revolute" and data["n_samples"] == 25
    assert axis_angle_error_deg([0, 0, 1], data["direction"]) < 0.1
    assert data["radius_m"] == pytest.approx(0.4, abs=1e-3)
    assert axis_position_error_m([0.5, 0.1, 0.7], [0, 0, 1], data["origin"], data["direction"]) < 1e-3


def test_fit_trajectory_levels_a_hinge_toward_the_given_up(capsys, tmp_path):
    """A door's swing whose handle sways 1.5 mm along the hinge midway leans the fitted hinge; `--up z` (the
    default) pulls it toward vertical, `--up none` keeps the fit, `--up y` does the same in a y-up frame."""
    rng = np.random.default_rng(0)
    s = np.linspace(0, 1, 150)
    angles = np.radians(50) * s
    sway = 1.5e-3 * np.sin(np.pi * s)
    pts = np.c_[0.22 * np.cos(angles), 0.22 * np.sin(angles), sway] + rng.normal(0, 4e-4, (150, 3))

    def fitted(points, *options):
        path = tmp_path / "door.txt"
        path.write_text("\n".join(" ".join(f"{v:.6f}" for v in p) for p in points) + "\n")
        code, out, _ = run(capsys, "axis", "fit-trajectory", str(path), "--joint", "revolute", "--json", *options)
        assert code == 0
        return np.array(json.loads(out)["direction"])

    levelled, kept = fitted(pts), fitted(pts, "--up", "none")
    assert axis_angle_error_deg([0, 0, 1], levelled) < axis_angle_error_deg([0, 0, 1], kept) - 0.2
    np.testing.assert_allclose(fitted(pts[:, [1, 2, 0]], "--up", "y"), levelled[[1, 2, 0]], atol=1e-6)


def test_fit_trajectory_bad_line_is_one_clear_error(capsys, tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("0 0 0\n0 0 oops\n")
    code, _, err = run(capsys, "axis", "fit-trajectory", str(path))
    assert code == 2
    assert "line 2" in err and "Traceback" not in err


@pytest.fixture(scope="module")
def drawer_recording(tmp_path_factory):
    seq = synthetic_sequence("drawer", np.random.default_rng(5), travel=0.10, n_frames=8, noise=DepthNoise.d415())
    path = tmp_path_factory.mktemp("rec") / "drawer"
    write_sequence(seq, path)
    return path, seq


def test_estimate_recording_json(capsys, drawer_recording):
    path, seq = drawer_recording
    code, out, _ = run(capsys, "axis", "estimate", str(path), "--json")
    assert code == 0
    data = json.loads(out)
    assert data["joint_type"] == "prismatic"
    assert data["estimator"] == "screw-grip"  # the default: the most accurate
    assert len(data["steps"]) == len(seq.frames)
    assert {"frame", "joint_type", "origin", "direction"} <= set(data["steps"][-1])
    assert axis_angle_error_deg(seq.true_axis.direction, data["direction"]) < 3.0


def test_verbose_estimate_logs_its_config_and_every_frame(capsys, drawer_recording):
    """docs/quickstart.md: `deploy --verbose ...` logs the resolved config and every estimate; axis estimate too."""
    path, seq = drawer_recording
    code, _, err = run(capsys, "--verbose", "axis", "estimate", str(path), "--json")
    assert code == 0
    assert "estimate config: filter sim" in err and "estimator screw-grip" in err
    frames = [line for line in err.splitlines() if "deploy.estimate_recording: frame " in line]
    assert len(frames) == len(seq.frames) and "prismatic axis, direction" in frames[-1]
    code, _, err = run(capsys, "axis", "estimate", str(path), "--json")
    assert code == 0 and "estimate config" not in err


def test_estimate_uses_the_gripper_path_and_views(capsys, drawer_recording, tmp_path):
    path, seq = drawer_recording
    code, out, _ = run(capsys, "axis", "estimate", str(path), "--view", "--rrd", str(tmp_path / "a.rrd"), "--json")
    data = json.loads(out)
    assert code == 0 and data["gripper_path"] and data["filter"]["profile"] == "sim"  # truth.json: simulated
    assert data["rrd"] == str(tmp_path / "a.rrd") and not (path / "axis.rrd").exists()  # not into the input
    found = entities(tmp_path / "a.rrd")
    assert found["/world/camera/image/mask"]["rows"] == len(seq.frames)
    assert found["/world/axis/estimated"]["rows"] == sum(s["joint_type"] is not None for s in data["steps"])


def test_estimate_with_bad_config_names_the_field(capsys, drawer_recording, tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[filter]\neps = 0\n")
    code, _, err = run(capsys, "axis", "estimate", str(drawer_recording[0]), "--config", str(cfg))
    assert code == 2
    assert "filter.eps" in err and str(cfg) in err


def test_estimate_missing_recording(capsys, tmp_path):
    code, _, err = run(capsys, "axis", "estimate", str(tmp_path / "none"))
    assert code == 2
    assert str(tmp_path / "none") in err


def test_axis_demo_prints_every_estimator(capsys):
    code, out, _ = run(capsys, "axis", "demo", "--seed", "1")
    assert code == 0
    for name in ("paper-obb", "screw", "screw-grip", "trajectory"):
        assert name in out


def test_open_drawer_in_simulation_json(capsys, tmp_path):
    code, out, err = run(capsys, "open-drawer", "--world", "box", "--seed", "1", "--distance", "0.15", "--run-dir",
                         str(tmp_path / "run"), "--view", "--json")
    data = json.loads(out)
    lines = [line for line in err.splitlines() if line.startswith("step ")]
    assert len(lines) == data["steps"] + 1, err  # one line per estimate: after the first pull and every step
    assert re.fullmatch(r"step 0: opened 0\.0\d\d m, axis prismatic from .+, confidence \d\.\d\d", lines[0].strip())
    quickstart = (Path(__file__).resolve().parents[1] / "docs" / "quickstart.md").read_text()
    for line in lines:  # every source a step names is one the quickstart explains
        source = re.search(r" from (.+), confidence", line).group(1)
        assert f"`{source}`" in quickstart, line
    found = entities(tmp_path / "run" / "episode.rrd")
    assert found["/world/axis/estimated"]["rows"] == len(lines) and found["/world/axis/true"]["rows"] == 1
    assert "Pinhole:image_from_camera" in found["/world/camera/image"]["components"]
    assert code == 0 and data["success"] and data["true_opened_m"] >= 0.15
    assert {"success", "opened_m", "target_m", "steps", "axis", "stop_reason", "run_dir", "axis_angle_error_deg",
            "axis_position_error_m", "true_opened_m", "filter"} <= set(data)
    assert data["filter"] == {"profile": "sim", "radius_m": 0.05, "eps": 100}  # simulation: the paper's sim setting
    assert data["axis"]["joint_type"] == "prismatic"
    assert (tmp_path / "run" / "report.png").is_file()
    frames = len((tmp_path / "run" / "frames" / "frames.jsonl").read_text().splitlines())
    assert data["rrd"] == {"path": str(tmp_path / "run" / "episode.rrd"), "live": False}  # no display here
    _assert_episode_view(found, frames, steps=len(lines))
    code, out, err = run(capsys, "export", str(tmp_path / "run"), "--format", "rrd", "--out", str(tmp_path / "run.rrd"))
    exported = entities(tmp_path / "run.rrd")  # the run folder's recording and steps.json, exported
    assert code == 0 and exported["/world/object/cloud"]["rows"] == len(lines), err
    assert exported["/world/axis/estimated"]["rows"] == len(lines) and "/world/paths/00/executed" in exported
    assert "/world/panda/visual_geometries/panda_link3/visual_0" in exported
    assert exported["/joints/panda_joint4/commanded"]["rows"] == frames


def _assert_episode_view(found: dict, frames: int, steps: int) -> None:
    """An episode's .rrd: the robot from its URDF posed by the joints, the joints and their commands, compressed
    colour and depth images, and per step the clouds and the axis with its confidence."""
    meshes = [e for e in found if e.startswith("/world/panda/visual_geometries/")]
    assert len(meshes) >= 8 and all("Asset3D:blob" in found[e]["components"] for e in meshes)
    for joint in (f"panda_joint{i}" for i in range(1, 8)):
        assert "Transform3D:child_frame" in found[f"/world/robot_joints/{joint}"]["components"]
        assert found[f"/world/robot_joints/{joint}"]["rows"] > frames  # every frame, and during the motions
        for kind in ("measured", "commanded"):
            assert found[f"/joints/{joint}/{kind}"]["rows"] > frames and "Scalars:scalars" in found[
                f"/joints/{joint}/{kind}"]["components"]
    assert found["/world/camera/image/color"]["rows"] == frames
    assert "EncodedImage:blob" in found["/world/camera/image/color"]["components"]  # JPEG
    assert "EncodedDepthImage:blob" in found["/world/camera/depth/image"]["components"]  # depth as depth
    assert found["/world/camera/depth/image"]["rows"] == frames
    for name in ("cloud", "moving_part", "handle"):
        assert found[f"/world/object/{name}"]["rows"] == steps, name
    assert found["/axis/confidence"]["rows"] == steps and found["/world/grasp"]["rows"] == 1
    assert "LineStrips3D:strips" in found["/world/paths/00/planned"]["components"]


def test_open_door_that_falls_short_exits_non_zero(capsys, tmp_path):
    """A door the arm cannot follow to the target: its config ends joint 1's range at -0.25 rad, which the arc
    about the hinge crosses after about 10 deg (CAN driver on simulated motors)."""
    robot = tmp_path / "panda_short_reach.toml"
    text = PANDA_SIM_CONFIG.read_text()
    robot.write_text(text.replace('name = "panda_joint1"\n', 'name = "panda_joint1"\nq_min = -0.25\n')
                     .replace("q_ready = [-0.4458,", "q_ready = [-0.2,"))  # the start within the narrowed range
    code, out, _ = run(capsys, "open-door", "--world", "box", "--seed", "0", "--angle", "45", "--arm", "sim-can",
                       "--robot", str(robot), "--run-dir", str(tmp_path / "run"), "--json")
    data = json.loads(out)
    assert code == 1 and not data["success"] and data["stop_reason"] == StopReason.ARM_ERROR
    assert data["message"].startswith("safety stop: joint panda_joint1 position -0.25")
    assert "is below its limit -0.2500" in data["message"]
    assert data["axis"]["joint_type"] == "revolute"
    assert 3.0 < data["true_opened_deg"] < 45.0  # it had started opening
    steps = json.loads((tmp_path / "run" / "steps.json").read_text())
    assert steps["result"]["stop_reason"] == StopReason.ARM_ERROR and (tmp_path / "run" / "report.png").is_file()


def test_bench_open_json_keys(capsys):
    code, out, _ = run(capsys, "bench", "open", "--task", "drawer", "--distance", "0.1", "--episodes", "1",
                       "--split", "train", "--seed", "1", "--json")
    data = json.loads(out)
    assert code == 0
    assert set(data) >= {"task", "target_m", "split", "policy", "episodes", "success_rate", "mean_opened_m",
                         "axis_angle_error_deg_median", "seconds_per_episode", "failures"}
    assert data["target_m"] == 0.1
    assert data["episodes"] == 1 and 0.0 <= data["success_rate"] <= 1.0


class _NoEpisodes:
    """An executor that runs nothing (bench_open's bookkeeping without the episodes' cost)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        pass

    def map(self, fn, jobs):
        return iter(())


@pytest.mark.parametrize(("workers", "episodes", "warned"), [(3, 10, True), (2, 10, False), (3, 2, False)])
def test_bench_open_warns_when_workers_exceed_the_cores(monkeypatch, caplog, workers, episodes, warned):
    """More worker processes than cores: one warning line (timings include waiting); the JSON states `workers`."""
    import os

    from deploy.bench import open as bench

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.setattr(bench, "make_executor", lambda workers, ray_address: _NoEpisodes())
    data = bench.bench_open("drawer", 0.3, episodes=episodes, workers=workers, segmenter="rgbd", world="box")
    assert data["workers"] == workers
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert lines == ([f"--workers {workers} is above this machine's 2 cores: episodes wait for a core, so their "
                      "seconds and frame times include that waiting; give --workers 2 or fewer for timings"]
                     if warned else [])
    assert bench.bench_open("drawer", 0.3, episodes=episodes, workers=workers, segmenter="rgbd",
                            ray_address="local", world="box")["workers"] is None


def test_bench_help_offers_only_what_the_command_takes(capsys):
    """bench open has no --camera and refuses classical; bench arm's motor count follows the robot."""
    _, out, _ = run(capsys, "bench", "open", "--help")
    flat = " ".join(re.sub(r"[│╭╮╰╯─]", " ", out).split())
    assert "--camera sim" not in flat and "classical: no weights" not in flat and "Not classical, which" in flat
    _, out, _ = run(capsys, "bench", "arm", "--help")
    flat = " ".join(re.sub(r"[│╭╮╰╯─]", " ", out).split())
    assert "(8 simulated motors)" not in flat and "8 for panda_sim, 7 for damiao_6dof" in flat


def test_fit_trajectory_without_orientations_hinges_a_gripper_whose_fingers_let_the_handle_turn(capsys, tmp_path):
    """A gripper's path (a recording's tool.txt): its grip point swings about the hinge, but the handle turns in
    the fingers, so the gripper turns only 0.95x the door's angle. Fitted with that turn the hinge lands 21 mm off;
    `--no-orientations` fits the grip point's circle (0.01 mm)."""
    rng = np.random.default_rng(1)
    angles = np.radians(np.linspace(0, 60, 120))
    pts = np.c_[0.5 + 0.4 * np.cos(angles), 0.1 + 0.4 * np.sin(angles), np.full_like(angles, 0.7)]
    pts += rng.normal(0, 1e-4, pts.shape)
    quats = Rotation.from_euler("z", 0.95 * angles[:, None]).as_quat()
    path = tmp_path / "tool.txt"
    path.write_text("\n".join(" ".join(f"{v:.6f}" for v in (*p, *q)) for p, q in zip(pts, quats, strict=True)) + "\n")

    def hinge_error(*options):
        code, out, _ = run(capsys, "axis", "fit-trajectory", str(path), "--joint", "revolute", "--json", *options)
        assert code == 0
        data = json.loads(out)
        return axis_position_error_m([0.5, 0.1, 0.7], [0, 0, 1], data["origin"], data["direction"]), data

    turned, with_turns = hinge_error()
    kept, without = hinge_error("--no-orientations")
    assert with_turns["orientations"] and not without["orientations"]
    assert kept < 1e-3 < turned, (kept, turned)


def _command_paths(command, path=()):
    """Every command's argument path below `command` (groups included)."""
    yield path
    for name, sub in getattr(command, "commands", {}).items():
        yield from _command_paths(sub, (*path, name))


def test_flags_show_no_value_in_any_help(capsys):
    """`--json` is a flag: the help must not show it as `--json <bool>`, which reads as if `--json true` worked."""
    from deploy.cli import build_command

    paths = list(_command_paths(build_command()))
    assert len(paths) > 30
    for path in paths:
        code, out, _ = run(capsys, *path, "--help")
        assert code == 0 and "--help" in out, path
        assert "<bool>" not in out, f"deploy {' '.join(path)} --help shows a flag's value type"


@pytest.mark.parametrize("command", [("arm", "status"), ("arm", "scan"), ("axis", "demo"), ("models", "check"),
                                     ("calibrate", "hand-eye", "--dry-run")])
def test_tables_fit_80_columns_without_cutting_a_name(capsys, monkeypatch, command):
    """As in a terminal of COLUMNS=80: no line is wider and no cell is cut to "…" (`pand…` for panda_joint1)."""
    from deploy.commands import output

    monkeypatch.setattr(output.console, "width", 80)
    code, out, _ = run(capsys, *command)
    assert code in (0, 1) and ("┃" in out or "─" in out), out  # models check: 1 without the weights
    assert "…" not in out, out
    assert max(len(line) for line in out.splitlines()) <= 80, out
    if command == ("arm", "status"):
        assert "panda_joint1" in out


def test_a_wide_table_keeps_every_name_whole(capsys, monkeypatch):
    from deploy.commands import output

    monkeypatch.setattr(output.console, "width", 80)
    names = [f"a_rather_long_motor_name_{i}" for i in range(3)]
    output.print_table("wide", [f"column_{i}" for i in range(9)], [[n, *[f"{i * 1.2345:.4f}"] * 8] for i, n in
                                                                     enumerate(names)])
    out = capsys.readouterr().out
    assert all(n in out for n in names) and "…" not in out, out
    assert max(len(line) for line in out.splitlines()) <= 80, out
