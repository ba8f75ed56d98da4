"""Arm bring-up safety on the real driver over the virtual CAN bus and simulated Damiao motors: moves end on their
goal or fail naming the joint, inside the joint limits; a zero counts only when the motor answered; --json keeps
stdout JSON; repeated Ctrl-C cannot cut the stop, the motor report, the bus shutdown or the run folder short."""

import io
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from cli_run import one_line, run

from deploy.arm_bringup import GOAL_MARGIN_RAD, GOAL_TOLERANCE_RAD, execute, plan
from deploy.control.state import StopReason
from drivers.arm.can_bus import CanBus
from drivers.arm.robot_config import load_robot_config
from drivers.errors import ArmError, CanBusError
from drivers.interrupts import Interrupted, interrupts
from sim_fallback.can_motors import GravityLoad, IntegratedMotors
from sim_fallback.devices import sim_can_arm

ROOT = Path(__file__).resolve().parents[1]
PANDA = load_robot_config("panda_sim")
DAMIAO = load_robot_config("damiao_6dof")


def _deploy(*args: str, **env: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "deploy", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1", **env))


# --- finding 1: gravity -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("args", [["move", "--pose", "0.4", "0", "0.5", "0", "90", "0"],
                                  ["jog", "--joint", "joint1", "--delta", "0.05"]])
def test_gravity_compensated_moves_on_the_damiao_template_end_on_their_goal(capsys, args):
    code, out, err = run(capsys, "arm", *args, "--robot", "damiao_6dof", "--yes", "--json")
    data = json.loads(out)
    assert code == 0, err
    assert data["max_joint_error_rad"] < GOAL_TOLERANCE_RAD
    assert np.abs(np.array(data["q"]) - data["q_goal"]).max() < GOAL_TOLERANCE_RAD


def test_a_move_that_does_not_reach_its_goal_fails_naming_the_joint_and_the_causes():
    config = DAMIAO.model_copy(update={"gravity_compensation": False})
    arm, motors = sim_can_arm(config)
    motors.backend = IntegratedMotors(gravity=GravityLoad(DAMIAO))  # a load the driver does not model
    with pytest.raises(ArmError) as caught, arm:
        p = plan(arm, config, "jog", joint="joint1", delta=0.05)
        execute(arm, config, p)
    message = str(caught.value)
    assert re.search(r"jog: joint joint\d ended 0\.\d+ rad from its goal", message), message
    assert "gravity model" in message and "gains" in message and "load" in message
    assert not any(m.enabled for m in motors.motors)


# --- finding 2: joint limits ------------------------------------------------------------------------------------


def test_goals_keep_a_margin_inside_the_joint_limits(capsys):
    code, _, err = run(capsys, "arm", "jog", "--joint", "panda_joint1", "--delta", "3.41", "--yes")
    line = one_line(err)
    assert code == 2 and "panda_joint1 goal 2.964 rad" in line and f"{GOAL_MARGIN_RAD} rad margin" in line
    assert "[-2.947, 2.947]: choose a smaller --delta" in line
    q_max = PANDA.safety_limits(PANDA.kinematics()).q_max[0]
    delta = q_max - GOAL_MARGIN_RAD - 0.001 - PANDA.q_ready[0]
    code, out, err = run(capsys, "arm", "jog", "--joint", "panda_joint1", "--delta", delta, "--yes", "--json")
    assert code == 0, err
    assert json.loads(out)["q"][0] <= q_max


def test_a_joint_measured_past_its_limit_stops_the_move():
    joints = [PANDA.joints[0].model_copy(update={"kp": 2.0, "kd": 0.0}), *PANDA.joints[1:]]  # undamped: overshoots
    config = PANDA.model_copy(update={"joints": joints})
    arm, motors = sim_can_arm(config)
    with pytest.raises(ArmError, match=r"jog: joint panda_joint1 measured 2\.96\d+ rad, 0\.0\d+ rad past its limits "
                                       r"\[-2\.967, 2\.967\]: the joint overshoots; raise kd"), arm:
        high = arm.guard.limits.q_max[0] - GOAL_MARGIN_RAD
        p = plan(arm, config, "jog", joint="panda_joint1", delta=high - 0.001 - arm.state().q[0])
        execute(arm, config, p)
    assert not any(m.enabled for m in motors.motors)


# --- finding 3: zero ----------------------------------------------------------------------------------------------


def test_zero_fails_when_the_motor_does_not_answer(capsys):
    code, out, err = run(capsys, "arm", "zero", "--joint", "panda_joint2", "--yes", "--sim-fault",
                         "silent:panda_joint2")
    line = one_line(err)
    assert code == 2 and "zeroed" not in out
    assert "motor panda_joint2 (CAN id 2, master 0x12) did not answer the disable: not zeroed" in line
    assert "deploy arm scan" in line


# --- finding 4: prompts with --json -----------------------------------------------------------------------------


def test_with_json_the_plan_and_the_prompt_go_to_stderr(capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", io.StringIO("y\n"))
    code, out, err = run(capsys, "arm", "jog", "--joint", "panda_joint1", "--delta", "0.05", "--json")
    assert code == 0 and json.loads(out)["q_goal"][0] == pytest.approx(PANDA.q_ready[0] + 0.05, abs=1e-3)
    assert "jog plan" in err and "q_goal" in err and "Run this motion now?" in err
    monkeypatch.setattr("sys.stdin", io.StringIO("n\n"))
    code, out, err = run(capsys, "arm", "enable", "--json")
    assert code == 1 and out.strip() == "" and "Enable the motors" in err  # click echoes one space


# --- finding 5: repeated Ctrl-C while stopping ------------------------------------------------------------------


def test_a_second_signal_while_stopping_cannot_cut_the_disable_the_report_or_the_bus_shutdown():
    arm, motors = sim_can_arm(PANDA)
    for t in (0.05, 0.06):  # on the motors' clock: while holding, then while the stop damps (0.3 s)
        motors.schedule(t, lambda: os.kill(os.getpid(), signal.SIGINT))
    with pytest.raises(Interrupted) as caught, interrupts(), arm:
        while True:
            arm.sync()
    states = caught.value.motors
    assert len(states) == 8 and not any(s["enabled"] for s in states)
    assert not any(m.enabled for m in motors.motors)
    with pytest.raises(ArmError, match="was disconnected"):  # disconnect ran to its end
        arm.connect()
    with pytest.raises(CanBusError):  # the bus was shut down
        arm.bus.send(1, bytes(8))


def test_two_quick_ctrl_c_on_the_cli_keep_the_motor_report_and_shut_the_bus_down():
    process = _deploy("arm", "enable", "--yes", "--hold", "30", "--json", "--arm", "sim-can")
    while "enabled; holding" not in process.stderr.readline():
        assert process.poll() is None, process.communicate()
    for _ in range(2):
        process.send_signal(signal.SIGINT)
        time.sleep(0.01)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 130
    assert "error: stopped by SIGINT (Ctrl-C); all 8 motors disabled" in err
    motors = json.loads(out)["motors"]
    assert len(motors) == 8 and not any(m["enabled"] for m in motors)
    assert "not properly shut down" not in err and "Traceback" not in err


# --- findings 7 and 8: repeated Ctrl-C during an opening --------------------------------------------------------


def test_repeated_ctrl_c_during_an_opening_still_finishes_the_run_folder_with_the_motors(tmp_path):
    run_dir = tmp_path / "run"
    frames = run_dir / "frames" / "frames.jsonl"
    process = _deploy("open-drawer", "--world", "box", "--arm", "sim-can", "--seed", "1", "--run-dir", str(run_dir))
    end = time.monotonic() + 120
    while not (frames.exists() and frames.read_text().count("\n") >= 3):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)
    for gap_s in (0.02, 0.1, 0.3):
        process.send_signal(signal.SIGINT)
        time.sleep(gap_s)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130 and "Traceback" not in err
    assert f"all 8 motors disabled; the run folder {run_dir} holds the frames, steps.json and report.png" in err
    steps = json.loads((run_dir / "steps.json").read_text())
    assert steps["result"]["stop_reason"] == StopReason.INTERRUPTED
    assert len(steps["motors"]) == 8 and not any(m["enabled"] for m in steps["motors"])
    assert (run_dir / "report.png").stat().st_size > 0


# --- finding 6: a missing adapter library -----------------------------------------------------------------------


def test_a_missing_adapter_library_is_one_line_naming_what_to_install(tmp_path):
    """slcan without pyserial: a `serial` module that fails to import stands first on the path, so the library
    is missing whether or not this machine has pyserial."""
    (tmp_path / "no_pyserial").mkdir()
    (tmp_path / "no_pyserial" / "serial.py").write_text('raise ImportError("No module named \'serial\'")\n')
    text = (ROOT / "drivers/arm/configs/damiao_6dof.toml").read_text()
    robot = tmp_path / "slcan.toml"
    robot.write_text(text.replace('interface = "socketcan"', 'interface = "slcan"')
                     .replace('channel = "can0"', 'channel = "/dev/ttyACM0"'))
    path = os.pathsep.join(filter(None, [str(tmp_path / "no_pyserial"), os.environ.get("PYTHONPATH")]))
    process = _deploy("arm", "scan", "--arm", "can", "--robot", str(robot), PYTHONPATH=path)
    _, err = process.communicate(timeout=60)
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("pybullet build time")]
    assert process.returncode == 2 and len(lines) == 1, err
    assert "CAN interface 'slcan' cannot be used" in lines[0] and "pip install pyserial" in lines[0]
    assert "ip link" not in lines[0]
    with pytest.raises(CanBusError, match="cannot be opened.*ip link show"):  # an unknown interface: as before
        CanBus("can0", "no-such-interface")


# --- finding 9: arm commands' messages and docs -----------------------------------------------------------------


def test_arm_commands_point_sim_to_sim_can_and_unreachable_poses_to_another_pose(capsys):
    code, _, err = run(capsys, "arm", "status", "--arm", "sim")
    line = one_line(err)
    assert code == 2 and "use --arm sim-can" in line and "--camera" not in line
    code, _, err = run(capsys, "arm", "move", "--pose", "2", "0", "0.5", "0", "90", "0", "--dry-run")
    line = " ".join(err.split())
    assert code == 2 and "unreachable" in line and "give another --pose" in line and "object" not in line


def test_status_says_the_motors_were_disabled_afterwards(capsys):
    code, out, _ = run(capsys, "arm", "status")
    assert code == 0 and "then damped; all 8 motors disabled" in out
    code, out, _ = run(capsys, "arm", "status", "--json")
    after = json.loads(out)["motors_after_stop"]
    assert code == 0 and len(after) == 8 and not any(m["enabled"] for m in after)


def test_arm_doc_commands_name_joints_of_their_robot():
    text = " ".join((ROOT / "docs" / "arm.md").read_text().split())
    commands = re.findall(r"`(deploy arm [^`]*--joint [^`]*)`", text)
    assert commands
    for command in commands:
        joint = re.search(r"--joint (\S+)", command).group(1)
        robot = re.search(r"--robot (\S+)", command)
        assert robot is not None or joint in PANDA.joint_names, f"{command}: {joint} is not a joint of panda_sim"


def test_bring_up_moves_keep_to_the_robot_configs_joint_speed(tmp_path, capsys):
    """A joint the config slows to 0.3 rad/s (below its URDF limit) is planned at a share of that, not of the
    URDF's: planned faster, the jog had tripped the safety layer's speed limit halfway."""
    text = (ROOT / "drivers/arm/configs/damiao_6dof.toml").read_text()
    robot = tmp_path / "slow.toml"
    robot.write_text(text.replace("v_max = 2.0", "v_max = 0.3", 1))
    code, out, _ = run(capsys, "arm", "jog", "--arm", "sim-can", "--robot", robot, "--joint", "joint1", "--delta",
                       "0.3", "--dry-run", "--json")
    assert code == 0 and json.loads(out)["duration_s"] >= 0.3 / (0.2 * 0.3)  # BRINGUP_SPEED of 0.3 rad/s
