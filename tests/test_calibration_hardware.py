"""`deploy calibrate` on other cameras and arms than the PyBullet rig: the real CAN driver on simulated Damiao motors
(sim-can) against ground truth, a D415 that is not attached, a CAN arm without its config, recordings refused, the
dry run, and the confirmation before a real arm's first motion."""

import itertools
import json

import numpy as np
import pytest
import typer

from calibration.poses import PoseConfig
from calibration.routine import RoutineConfig
from calibration.store import load_hand_eye
from deploy.calibration_devices import SPEED_FRACTION, DeviceChoice, Devices, pivot_from_record
from deploy.cli import main
from drivers.arm.can_arm import CanArm
from drivers.arm.can_bus import CanBus
from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config
from sim_fallback.can_motors import SimMotorBus

TARGET_MM, TARGET_DEG = 3.0, 0.3  # issue 10: 15 poses at 640x480
_channels = itertools.count()


@pytest.fixture
def calib_dir(tmp_path, monkeypatch):
    folder = tmp_path / "calibration"
    folder.mkdir()
    monkeypatch.setenv("AXISLOOP_CALIBRATION_DIR", str(folder))
    return folder


@pytest.fixture
def can_robot(tmp_path):
    """A robot config on a private virtual CAN channel with simulated Damiao motors answering in their own thread,
    as a real arm would (`--arm can`): (config path, motors)."""
    text = PANDA_SIM_CONFIG.read_text().replace('channel = "axisloop-sim"', f'channel = "calib-hw-{next(_channels)}"')
    path = tmp_path / "arm.toml"
    path.write_text(text)
    motors = SimMotorBus(load_robot_config(path)).start()
    yield path, motors
    motors.close()


def untouched(motors: SimMotorBus) -> bool:
    return all(not m.enabled and m.mit_frames == 0 for m in motors.motors)


def run_json(args, capsys) -> dict:
    assert main(args) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_sim_can_calibrates_within_the_target(setup, calib_dir, opened, capsys):
    data = run_json(["calibrate", "hand-eye", "--setup", setup, "--arm", "sim-can", "--poses", "15", "--json"], capsys)
    assert data["samples"] == 15 and data["refined"]
    assert data["true_error_mm"] <= TARGET_MM and data["true_error_deg"] <= TARGET_DEG, data
    assert data["file"] == str(calib_dir / "handeye_panda-sim_sim-d415.yaml")  # camera serial, robot config name
    (dev,) = opened
    assert isinstance(dev.arm, CanArm)
    assert all(m.mit_frames > 1000 for m in dev.motors.motors[:7])  # every joint was driven over the CAN bus
    assert not any(m.enabled for m in dev.motors.motors)  # left disabled
    assert np.allclose(dev.arm.state().q, dev.rig.q_start, atol=0.01)  # back at the start
    # a check on a real arm turns about the board centre the stored calibration gives: compare with the truth
    record, T_start = load_hand_eye(data["file"]), dev.kin.fk(dev.rig.q_start)
    true_board = dev.rig.true_board if setup == "eye-to-hand" else np.linalg.inv(T_start) @ dev.rig.true_board
    true_centre = true_board[:3, :3] @ record.board.center_m + true_board[:3, 3]
    assert np.linalg.norm(np.array(pivot_from_record(record, T_start)) - true_centre) < 0.003
    if setup == "eye-in-hand":
        check = run_json(["calibrate", "check", "--arm", "sim-can", "--poses", "4", "--point", "--json"], capsys)
        assert check["samples"] == 4 and check["reprojection_px"] < 1.0 and check["point_true_error_mm"] < 3.0
        assert not any(m.enabled for m in opened[-1].motors.motors)


def test_a_missing_d415_is_one_clear_error_before_the_arm_opens(calib_dir, capsys):
    """A serial no camera has: the same error path with or without a camera attached; the camera opens first, so a
    real arm's bus (can0, absent here) is never reached."""
    args = ["calibrate", "hand-eye", "--camera", "d415:000000000000", "--arm", "can", "--robot", "damiao_6dof",
            "--pivot-mm", "0", "0", "30", "--yes"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "RealSense camera" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not list(calib_dir.iterdir())


@pytest.mark.parametrize(("args", "message"), [
    (["hand-eye", "--camera", "d415", "--arm", "can"], "--arm can needs --robot CONFIG.toml"),
    (["check", "--camera", "d415"], "--arm can needs --robot CONFIG.toml"),  # a D415 defaults to the CAN arm
    (["hand-eye", "--camera", "d415", "--robot", str(PANDA_SIM_CONFIG)], "--pivot-mm X Y Z is needed on a real arm"),
    (["hand-eye", "--camera", "replay:/data/drawer.bag"], "a recording cannot show"),
    (["hand-eye", "--camera", "replay:/data/frames", "--arm", "can"], "a recording cannot show"),
    (["intrinsics", "--camera", "sim", "--arm", "can", "--robot", str(PANDA_SIM_CONFIG)], "cannot see --arm can"),
    (["hand-eye", "--arm", "ideal"], "is not one of sim, sim-can, can"),
    (["hand-eye", "--camera", "usb"], "is not one of sim, realsense[:SERIAL], d415[:SERIAL], d435[:SERIAL]"),
    (["hand-eye", "--arm", "sim-can", "--robot", "damiao_6dof"], "is not the simulated Panda"),
])
def test_bad_device_choices_are_one_clear_error(args, message, calib_dir, capsys):
    assert main(["calibrate", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not list(calib_dir.iterdir())


def test_a_robot_config_that_is_not_the_panda_is_named_by_its_file(calib_dir, tmp_path, capsys):
    robot = tmp_path / "my_arm.toml"
    robot.write_text((PANDA_SIM_CONFIG.parent / "damiao_6dof.toml").read_text())
    assert main(["calibrate", "hand-eye", "--arm", "sim-can", "--robot", str(robot)]) == 2
    err = capsys.readouterr().err
    assert f"robot config {robot.resolve()} is not the simulated Panda" in " ".join(err.split())

def test_dry_run_lists_the_stations_and_moves_nothing(calib_dir, opened, capsys):
    data = run_json(["calibrate", "hand-eye", "--arm", "sim-can", "--poses", "12", "--dry-run", "--json"], capsys)
    (dev,) = opened
    assert data["dry_run"] and data["board_visible"] and data["robot"] == "panda-sim"
    assert len(data["stations"]) == 12
    kin = dev.kin
    margin = PoseConfig().joint_margin_rad
    for s in data["stations"]:
        q = np.array(s["q"])
        assert np.all(q >= kin.q_min + margin - 1e-3) and np.all(q <= kin.q_max - margin + 1e-3)
        assert np.allclose(kin.fk(q)[:3, 3], s["tool_position_m"], atol=1e-3)  # the tool pose IK was asked for
    assert 5.0 < data["max_turn_deg"] < 45.0 and data["duration_s"] > 0
    assert untouched(dev.motors)  # probed only: never enabled, no MIT command
    assert np.allclose(data["q_start"], dev.rig.q_start, atol=1e-3)
    assert not list(calib_dir.iterdir())

    assert main(["calibrate", "check", "--dry-run"]) == 2  # nothing stored yet: the check has nothing to check
    assert "no hand-eye calibration for camera sim-d415 on robot panda-sim" in capsys.readouterr().err
    assert main(["calibrate", "intrinsics", "--arm", "sim", "--poses", "6", "--dry-run"]) == 0
    assert "dry run, nothing moved" in capsys.readouterr().out
    dev = opened[-1]
    assert dev.rig.world.clock.steps == 0  # not one physics step: the simulated arm never moved


def test_a_real_arm_asks_before_its_first_motion(can_robot):
    path, motors = can_robot
    robot = load_robot_config(path)
    c = robot.can
    arm = CanArm(robot, CanBus.from_config(c))
    dev = Devices(DeviceChoice("d415", "can", robot, (0.0, 0.0, 30.0)), None, arm, arm.kin, "0123",
                  robot.motion_limits(arm.kin, SPEED_FRACTION))
    asked = []

    def refuse(message: str) -> None:
        asked.append(message)
        raise typer.Abort()

    try:
        arm.probe()  # joints read, nothing enabled
        plan = dev.plan(RoutineConfig(poses=6, stations=PoseConfig(pivot_tool_m=dev.pivot())))
        with pytest.raises(typer.Abort):
            dev.start(plan, refuse)
        assert "'panda-sim' will visit 6 stations" in asked[0] and untouched(motors)
        dev.start(plan, asked.append)
        assert len(asked) == 2 and all(m.enabled for m in motors.motors)
    finally:
        arm.disconnect()
    motors.close()  # handles the frames still queued: the driver's last disables
    assert not any(m.enabled for m in motors.motors)
