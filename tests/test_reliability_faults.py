"""Arm faults end with every reachable motor disabled and the message naming any that is not: the CAN driver on
simulated motors (disable confirmation, the final motor states), the `--sim-fault` injections, and their end to
end result on `deploy arm ...`, `open*` and `calibrate` (exit code, one line, the JSON error object's motors)."""

import json
import re

import pytest

from deploy.cli import main
from deploy.control.state import StopReason
from drivers.arm.disable import disable_summary, with_summary
from drivers.arm.robot_config import load_robot_config
from drivers.errors import ArmError, CanBusError
from sim_fallback.devices import sim_can_arm
from sim_fallback.sim_faults import BUS_FAULTS, KINDS, SimFault

PANDA = load_robot_config("panda_sim")
JOG = ("arm", "jog", "--joint", "panda_joint1", "--delta", "0.3", "--yes", "--json")


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def _cycles(arm, n: int) -> None:
    for _ in range(n):
        arm.sync()


def _states(motors) -> dict[str, bool]:
    return {c.name: m.enabled for m, c in zip(motors.motors, motors.config.motors,
                                                                       strict=True)}


# --- the driver ------------------------------------------------------------------------------------------------


def test_a_silent_motor_is_named_as_disabled_by_its_timeout_and_the_others_by_the_disable():
    arm, motors = sim_can_arm(PANDA)
    with pytest.raises(ArmError) as caught, arm:
        _cycles(arm, 10)
        motors.motor("panda_joint6").faults.silent = True
        _cycles(arm, 50)
    message = str(caught.value)
    assert "watchdog: joint panda_joint6" in message
    assert ("all 8 motors disabled: panda_joint6 did not answer the disable but has disabled itself by its own 100 ms "
            "communication timeout") in message
    assert not any(_states(motors).values())  # the simulated motors agree: the silent one timed out
    assert motors.motor("panda_joint6").status.name == "COMMUNICATION_LOST"
    states = {s["name"]: s for s in caught.value.motors}
    assert states["panda_joint6"]["enabled"] is False and states["panda_joint6"]["status"] == "timed out"
    assert "100 ms communication timeout" in states["panda_joint6"]["cause"]
    assert all(not s["enabled"] and s["status"] == "disabled" for n, s in states.items() if n != "panda_joint6")


def test_after_a_bus_off_every_motor_disables_itself_by_its_timeout():
    arm, motors = sim_can_arm(PANDA)
    with pytest.raises(CanBusError) as caught, arm:
        _cycles(arm, 5)
        motors.inject_bus_off()
        _cycles(arm, 5)
    message = str(caught.value)
    assert "bus-off" in message
    assert "none answered the disable, but each has disabled itself by its own 100 ms" in message
    assert not any(_states(motors).values())  # a dead bus reaches nobody: their own timeouts disabled them
    assert {m.status.name for m in motors.motors} == {"COMMUNICATION_LOST"}
    assert [(s["enabled"], s["status"]) for s in caught.value.motors] == [(False, "timed out")] * 8


def test_error_passive_disables_every_motor_and_says_so():
    arm, motors = sim_can_arm(PANDA)
    with pytest.raises(CanBusError, match="error-passive.*; all 8 motors disabled$"), arm:
        motors.inject_error_passive()
        _cycles(arm, 5)
    assert not any(_states(motors).values())


def test_a_motor_whose_replies_are_lost_is_reported_unconfirmed_though_it_obeyed():
    arm, motors = sim_can_arm(PANDA)
    with pytest.raises(ArmError) as caught, arm:
        _cycles(arm, 5)
        motors.motor("panda_joint2").faults.drop_rate = 1.0
        _cycles(arm, 50)
    assert not motors.motor("panda_joint2").enabled  # it got the disable ...
    # ... which nothing confirmed: the driver can only tell its timeout has passed since the last command
    assert "panda_joint2 did not answer the disable but has disabled itself" in str(caught.value)


def test_a_clean_stop_confirms_every_motor():
    arm, motors = sim_can_arm(PANDA)
    with arm:
        _cycles(arm, 5)
    assert [s["status"] for s in arm.motor_states()] == ["disabled"] * 8 and not any(_states(motors).values())


def test_summaries():
    off = [{"name": "a", "enabled": False}, {"name": "b", "enabled": False}]
    assert disable_summary(off) == "all 2 motors disabled"
    assert with_summary("x: motors disabled; fix", off) == "x: motors disabled; fix"
    assert with_summary("bus-off: fix", off) == "bus-off: fix; all 2 motors disabled"
    one = [{"name": "a", "enabled": True}, {"name": "b", "enabled": False}]
    text = with_summary("x: motors disabled; fix", one)
    assert text.startswith("x: motors disabled except a, which did not answer") and text.endswith("; fix")
    assert with_summary(text, one) == text  # idempotent: the CLI may add it again


# --- fault injection ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "fault"), [
    ("bus-off", SimFault("bus-off")), ("silent:panda_joint2@1.5", SimFault("silent", "panda_joint2", 1.5)),
    ("Over-Temperature:gripper", SimFault("over-temperature", "gripper")), ("delay@0", SimFault("delay")),
])
def test_fault_text_parses(text, fault):
    assert SimFault.parse(text) == fault


@pytest.mark.parametrize(("text", "words"), [
    ("smoke", "unknown fault kind 'smoke'"), ("bus-off:panda_joint1", "fault of the whole bus"),
    ("silent@soon", "not a number of seconds"), ("silent@-1", "finite number of seconds"),
    ("silent@inf", "finite number of seconds"),
])
def test_bad_fault_text_says_what_is_allowed(text, words):
    with pytest.raises(ValueError, match=words):
        SimFault.parse(text)


def test_a_fault_waits_for_its_time_on_the_motors_clock():
    arm, motors = sim_can_arm(PANDA)
    SimFault("silent", "panda_joint4", 0.1).schedule(motors)
    with arm:
        _cycles(arm, int(0.05 * PANDA.control_rate_hz))
        assert not motors.motor("panda_joint4").faults.silent and arm.fault is None
        with pytest.raises(ArmError, match="panda_joint4"):
            _cycles(arm, int(0.1 * PANDA.control_rate_hz))


# (kind, what the one line says, which motors did not answer the disable: disabled by their communication timeout)
EXPECTED = {
    "bus-off": ("went bus-off", "all"), "error-passive": ("error-passive", "none"),
    "cable-pulled": ("watchdog: joint panda_joint1 .* sent no valid feedback", "all"),
    "silent": ("watchdog: joint panda_joint3", "panda_joint3"),
    "frame-loss": ("watchdog: joint panda_joint3", "panda_joint3"),
    "delay": ("watchdog: joint panda_joint3", "panda_joint3"),  # its answer to the disable comes late too
    "over-voltage": ("panda_joint3 .* reports over-voltage", "none"),
    "under-voltage": ("reports under-voltage", "none"), "over-current": ("reports over-current", "none"),
    "over-temperature": ("reports mos-over-temperature", "none"),
    "coil-over-temperature": ("reports coil-over-temperature", "none"),
    "communication-lost": ("reports communication-lost", "none"), "overload": ("reports overload", "none"),
}


def test_every_kind_has_an_expectation():
    assert sorted(EXPECTED) == sorted(KINDS)


@pytest.mark.parametrize("kind", KINDS)
def test_every_fault_mid_jog_ends_with_one_line_and_the_motors_state(capsys, kind):
    spec = f"{kind}@0.3" if kind in BUS_FAULTS else f"{kind}:panda_joint3@0.3"
    code, out, err = run(capsys, *JOG, "--sim-fault", spec)
    words, left = EXPECTED[kind]
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err
    data = json.loads(out)
    assert data["exit_code"] == 2 and data["error"] == lines[0].removeprefix("error: ")
    assert re.search(words, data["error"]), data["error"]
    timed = [m["name"] for m in data["motors"] if m["status"] == "timed out"]
    assert len(data["motors"]) == 8 and not any(m["enabled"] for m in data["motors"])
    assert timed == {"all": [m["name"] for m in data["motors"]], "none": []}.get(left, [left])
    assert "motors disabled" in data["error"] and "may still be enabled" not in data["error"]
    if timed:
        assert "disabled itself by its own 100 ms communication timeout" in data["error"]


@pytest.mark.parametrize("command", [("arm", "status"), ("arm", "enable", "--yes", "--hold", "0.1"),
                                     ("arm", "home", "--yes"), ("arm", "move", "--pose", "0.45", "0", "0.6", "0",
                                                                "90", "0", "--yes")])
def test_a_fault_at_once_is_refused_at_connect(capsys, command):
    code, _, err = run(capsys, *command, "--sim-fault", "over-current:panda_joint2")
    assert code == 2 and "panda_joint2" in err and "Traceback" not in err


def test_bus_commands_take_faults_too(capsys):
    code, out, _ = run(capsys, "arm", "scan", "--json", "--sim-fault", "silent:panda_joint2")
    assert code == 0 and [m["can_id"] for m in json.loads(out)["motors"]] == [1, 3, 4, 5, 6, 7, 8]
    code, out, _ = run(capsys, "arm", "disable", "--sim-fault", "silent:gripper")
    assert code == 1 and "except gripper, which did not answer" in " ".join(out.split())
    code, _, err = run(capsys, "arm", "zero", "--joint", "panda_joint1", "--yes", "--sim-fault", "bus-off")
    assert code == 2 and "did not answer the disable" in " ".join(err.split())  # never "zeroed" unconfirmed


@pytest.mark.parametrize(("args", "words"), [
    (("--sim-fault", "silent"), "--sim-fault breaks the simulated CAN arm: use it with --arm sim-can, not --arm ideal"),
])
def test_faults_need_the_simulated_can_arm(capsys, args, words):
    code, _, err = run(capsys, "arm", "status", "--arm", "ideal", *args)
    assert code == 2 and words in " ".join(err.split())


def test_an_unknown_joint_is_one_line(capsys):
    code, _, err = run(capsys, "arm", "status", "--sim-fault", "silent:elbow")
    assert code == 2 and "no motor 'elbow'" in err and "panda_joint1" in err


def test_a_fault_during_an_opening_names_the_joint_and_the_motors(capsys, tmp_path):
    code, out, _ = run(capsys, "open-drawer", "--arm", "sim-can", "--sim-fault", "silent:panda_joint2@1.0",
                       "--run-dir", tmp_path / "run", "--json")
    data = json.loads(out)
    assert code == 1 and data["stop_reason"] == StopReason.ARM_ERROR and "panda_joint2" in data["message"]
    assert not any(m["enabled"] for m in data["motors"])
    assert [m["name"] for m in data["motors"] if m["status"] == "timed out"] == ["panda_joint2"]
    assert (tmp_path / "run" / "steps.json").is_file() and (tmp_path / "run" / "report.png").is_file()


def test_a_fault_during_calibration_is_the_json_error_with_the_motors(capsys, tmp_path):
    code, out, err = run(capsys, "calibrate", "intrinsics", "--camera", "sim", "--arm", "sim-can", "--poses", "4",
                         "--yes", "--dir", tmp_path, "--sim-fault", "bus-off@0.5", "--json")
    data = json.loads(out)
    assert code == 2 and "bus-off" in data["error"] and "communication timeout" in data["error"]
    assert [(m["enabled"], m["status"]) for m in data["motors"]] == [(False, "timed out")] * 8
    assert not list(tmp_path.iterdir())  # nothing saved
