"""The `deploy` command line end to end, on files and recordings the tests make themselves."""

import json

import numpy as np
import pytest

from deploy.cli import main
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.synthetic.sequence import synthetic_sequence, write_sequence
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
    assert set(data) >= {"joint_type", "origin", "direction", "radius", "residual_m", "n_samples"}
    assert data["joint_type"] == "revolute" and data["n_samples"] == 25
    assert axis_angle_error_deg([0, 0, 1], data["direction"]) < 0.1
    assert data["radius"] == pytest.approx(0.4, abs=1e-3)
    assert axis_position_error_m([0.5, 0.1, 0.7], [0, 0, 1], data["origin"], data["direction"]) < 1e-3


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
    code, out, _ = run(capsys, "open-drawer", "--seed", "1", "--distance", "0.15", "--run-dir", str(tmp_path / "run"),
                       "--json")
    data = json.loads(out)
    assert code == 0 and data["success"] and data["true_opened"] >= 0.15
    assert {"success", "opened", "target", "steps", "axis", "stop_reason", "run_dir", "axis_angle_error_deg",
            "axis_position_error_m", "true_opened"} <= set(data)
    assert data["axis"]["joint_type"] == "prismatic"
    assert (tmp_path / "run" / "report.png").is_file()


def test_open_door_that_falls_short_exits_non_zero(capsys, tmp_path):
    code, out, _ = run(capsys, "open-door", "--seed", "0", "--angle", "20", "--run-dir", str(tmp_path / "run"),
                       "--json")
    data = json.loads(out)
    assert code == (0 if data["success"] else 1)
    assert data["axis"]["joint_type"] == "revolute"


def test_bench_open_json_keys(capsys):
    code, out, _ = run(capsys, "bench", "open", "--task", "drawer", "--target", "0.1", "--episodes", "1",
                       "--split", "train", "--seed", "1", "--json")
    data = json.loads(out)
    assert code == 0
    assert set(data) >= {"task", "target", "split", "policy", "episodes", "success_rate", "mean_opened",
                         "axis_angle_error_deg_median", "seconds_per_episode", "failures"}
    assert data["episodes"] == 1 and 0.0 <= data["success_rate"] <= 1.0
