"""`deploy arm ...` and `deploy bench arm` on simulated Damiao motors (sim-can) and the ideal arm."""

import io
import json
import shutil

import pytest

from deploy.cli import main
from drivers.arm.robot_config import PANDA_SIM_CONFIG


def run(capsys, *args):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("command", ["scan", "status", "enable", "disable", "zero", "home", "jog", "move"])
def test_every_arm_command_has_help_with_an_example(capsys, command):
    code, out, _ = run(capsys, "arm", command, "--help")
    assert code == 0 and "Example" in out


def test_scan_lists_the_simulated_motors(capsys):
    code, out, _ = run(capsys, "arm", "scan", "--arm", "sim-can", "--json")
    motors = json.loads(out)["motors"]
    assert code == 0 and [m["can_id"] for m in motors] == list(range(1, 9))
    assert motors[0] == {"can_id": 1, "master_id": 0x11, "status": "disabled", "p_max": 12.5, "v_max": 25.0,
                         "t_max": 200.0, "timeout_ms": 0.0, "fd": False}  # the factory timeout: never


def test_scan_of_an_empty_range_fails(capsys):
    code, _, err = run(capsys, "arm", "scan", "--first-id", "20", "--last-id", "21")
    assert code == 1 and "no motor answered" in err


def test_status_json(capsys):
    code, out, _ = run(capsys, "arm", "status", "--json")
    data = json.loads(out)
    assert code == 0 and len(data["joint_positions_rad"]) == 7
    assert data["tool_position_m"] == pytest.approx([0.45, 0, 0.7], abs=2e-3)
    assert [m["status"] for m in data["motors"]] == ["enabled"] * 8


def test_jog_moves_the_joint(capsys):
    code, out, _ = run(capsys, "arm", "jog", "--joint", "panda_joint1", "--delta", "0.2", "--yes", "--json")
    data = json.loads(out)
    assert code == 0 and not data["dry_run"]
    assert data["q"][0] == pytest.approx(data["q_start"][0] + 0.2, abs=0.01)


def test_dry_run_plans_without_moving(capsys):
    code, out, _ = run(capsys, "arm", "move", "--pose", "0.45", "0.1", "0.6", "0", "90", "0", "--dry-run", "--json")
    data = json.loads(out)
    assert code == 0 and data["dry_run"] and data["tool_goal_m"] == pytest.approx([0.45, 0.1, 0.6], abs=1e-3)
    assert "q" not in data and data["duration_s"] > 0


def test_declining_the_prompt_does_not_move(capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", io.StringIO("n\n"))
    code, out, _ = run(capsys, "arm", "home", "--arm", "ideal")
    assert code == 1 and "Run this motion now?" in out and "home done" not in out


def test_unsafe_or_unreachable_moves_are_one_clear_error(capsys):
    code, _, err = run(capsys, "arm", "move", "--pose", "2", "0", "0.6", "0", "90", "0", "--yes")
    assert code == 2 and "unreachable" in err and "Traceback" not in err
    code, _, err = run(capsys, "arm", "jog", "--joint", "panda_joint4", "--delta", "3", "--yes")
    assert code == 2 and "panda_joint4 goal" in err and "outside its limits" in err
    code, _, err = run(capsys, "arm", "jog", "--joint", "elbow", "--delta", "0.1", "--yes")
    assert code == 2 and "'elbow' is not one of" in err
    code, _, err = run(capsys, "arm", "status", "--robot", "missing.toml")
    assert code == 2 and "not found" in err


def test_enable_disable_zero(capsys):
    assert run(capsys, "arm", "enable", "--hold", "0.1", "--yes", "--clear-errors")[0] == 0
    code, out, _ = run(capsys, "arm", "disable")
    assert code == 0 and "8 motors" in out
    code, out, _ = run(capsys, "arm", "zero", "--joint", "panda_joint7", "--yes", "--json")
    assert code == 0 and json.loads(out) == {"joint": "panda_joint7", "can_id": 7, "zeroed": True}


def test_zero_of_a_joint_the_config_lacks_names_the_config_file(capsys, tmp_path):
    robot = tmp_path / "my_arm.toml"
    shutil.copyfile(PANDA_SIM_CONFIG, robot)
    code, _, err = run(capsys, "arm", "zero", "--joint", "elbow", "--robot", str(robot), "--yes")
    assert code == 2 and f"joint 'elbow' is not in robot config {robot.resolve()}:" in err and "Traceback" not in err

def test_bench_arm_json_keys(capsys):
    code, out, _ = run(capsys, "bench", "arm", "--samples", "20", "--seconds", "0.5", "--json")
    data = json.loads(out)
    assert code == 0
    for key in ("ik_ms_median", "ik_success_rate", "ruckig_ms_median", "loop_hz", "loop_jitter_ms_p99", "motors"):
        assert key in data
    assert data["motors"] == 8 and data["ik_success_rate"] > 0.9 and data["loop_hz"] > 50


@pytest.mark.parametrize("command", [["scan"], ["disable"], ["zero", "--joint", "panda_joint1", "--yes"]])
def test_bus_commands_refuse_an_arm_without_motors(capsys, command):
    code, _, err = run(capsys, "arm", *command, "--arm", "ideal")
    assert code == 2 and "needs --arm can or sim-can, not 'ideal'" in " ".join(err.split())
