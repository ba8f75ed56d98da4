"""Motors that stop themselves: the communication timeout is written and read back at enable, the simulated motors
disable themselves when no command comes for that long, and after a bus-off, a killed process or a pulled cable
every motor ends disabled with the JSON and message saying so."""

import json
import time

import pytest

from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import REG_TIMEOUT, Special, Status, param_read, param_write, special, unpack_param_reply
from drivers.arm.robot_config import RobotConfig, load_robot_config
from drivers.errors import ArmError
from sim_fallback.can_motors import SimMotorBus
from sim_fallback.devices import sim_can_arm
from tests.cli_run import run

PANDA = load_robot_config("panda_sim")


def test_enable_writes_each_motors_timeout_and_reads_it_back():
    arm, motors = sim_can_arm(PANDA)
    assert [m.timeout_steps for m in motors.motors] == [0] * 8  # the factory value: never
    with arm:
        assert [m.timeout_steps for m in motors.motors] == [2000] * 8  # 100 ms in 50 us steps
        assert [r["timeout_ms"] for r in arm.motor_report()] == [100.0] * 8


def test_a_motor_that_does_not_keep_its_timeout_is_refused_at_enable():
    """A firmware that answers the write but keeps its old value: the arm must not run without its motors' own
    watchdog."""
    arm, motors = sim_can_arm(PANDA)
    motors.motor("panda_joint3").timeout_locked = True
    with pytest.raises(ArmError, match=r"panda_joint3 .* holds a communication timeout of 0 ms after 100 ms"):
        arm.connect()
    arm.disconnect()
    assert not any(m.enabled for m in motors.motors)


def _exchange(bus: CanBus, motors: SimMotorBus, can_id: int, data: bytes, arbitration_id: int | None = None):
    bus.send(can_id if arbitration_id is None else arbitration_id, data)
    motors.poll()
    return bus.recv(0.01)


def test_a_simulated_motor_disables_itself_when_commands_stop_for_its_timeout():
    config = PANDA.model_copy(update={"can": PANDA.can.model_copy(update={"channel": "timeout-test"})})
    motors = SimMotorBus(config)
    with CanBus.from_config(config.can) as bus:
        reply = _exchange(bus, motors, 1, param_write(1, REG_TIMEOUT, 600), 0x7FF)  # 30 ms
        assert unpack_param_reply(bytes(reply.data)).value == 600
        assert unpack_param_reply(bytes(_exchange(bus, motors, 1, param_read(1, REG_TIMEOUT), 0x7FF).data)).value == 600
        _exchange(bus, motors, 1, special(Special.ENABLE))
        m = motors.motor(1)
        for _ in range(10):  # commands every 10 ms: it stays enabled
            motors.step(0.01)
            _exchange(bus, motors, 1, special(Special.ENABLE))
        assert m.enabled and m.status == Status.ENABLED
        motors.step(0.02)
        assert m.enabled  # 20 ms without a command
        motors.step(0.01)
        assert not m.enabled and m.status == Status.COMMUNICATION_LOST  # 30 ms: it disabled itself
        assert motors.motor(2).status == Status.DISABLED  # never enabled: nothing to time out
    motors.close()


def test_a_killed_process_leaves_every_motor_disabled_within_the_timeout():
    """Realtime, as on hardware: the control thread stops without a disable (the process died); the motors' own
    clock runs on the wall clock."""
    arm, motors = sim_can_arm(PANDA, lockstep=False)
    arm.connect()
    assert all(m.enabled for m in motors.motors)
    killed = time.perf_counter()
    arm.loop.stop()  # no more commands, no disable: what SIGKILL leaves
    while any(m.enabled for m in motors.motors) and time.perf_counter() - killed < 1.0:
        time.sleep(0.005)
    elapsed = time.perf_counter() - killed
    assert not any(m.enabled for m in motors.motors)
    assert {m.status for m in motors.motors} == {Status.COMMUNICATION_LOST}
    assert 0.09 <= elapsed <= 0.3  # the 100 ms timeout, give or take the motors' 1 ms polling and the load
    arm.disconnect()


def _jog(capsys, fault: str):
    code, out, err = run(capsys, "arm", "jog", "--arm", "sim-can", "--joint", "panda_joint1", "--delta", "0.3",
                         "--yes", "--sim-fault", fault, "--json")
    return code, json.loads(out), err


@pytest.mark.parametrize("fault", ["bus-off@0.2", "cable-pulled@0.2"])
def test_bus_off_or_a_pulled_cable_mid_jog_ends_with_every_motor_disabled_by_its_timeout(capsys, fault):
    code, data, err = _jog(capsys, fault)
    assert code == 2 and data["exit_code"] == 2 and "Traceback" not in err
    assert [(m["enabled"], m["status"], m["timeout_ms"]) for m in data["motors"]] == [(False, "timed out", 100.0)] * 8
    assert all("100 ms communication timeout" in m["cause"] for m in data["motors"])
    assert "none answered the disable, but each has disabled itself by its own 100 ms communication timeout" in \
        data["error"] and "may still be enabled" not in data["error"]


def test_the_driver_reports_what_the_simulated_motors_did():
    arm, motors = sim_can_arm(PANDA)
    with pytest.raises(ArmError) as caught, arm:
        for _ in range(5):
            arm.sync()
        motors.inject_bus_off()
        for _ in range(5):
            arm.sync()
    assert [s["enabled"] for s in caught.value.motors] == [m.enabled for m in motors.motors] == [False] * 8


def test_status_shows_each_motors_timeout(capsys):
    code, out, _ = run(capsys, "arm", "status", "--arm", "sim-can")
    assert code == 0 and "timeout_ms" in out and "100.00" in out


@pytest.mark.parametrize(("timeout_s", "ok"), [(0.1, True), (0.006, False)])
def test_a_motor_timeout_shorter_than_a_late_cycle_is_refused(timeout_s, ok):
    data = PANDA.model_dump(exclude={"source"})
    data["watchdog"]["motor_timeout_s"] = timeout_s  # 240 Hz with 2 late cycles allowed: 12.5 ms between commands
    if ok:
        assert RobotConfig.model_validate(data).watchdog.motor_timeout_s == timeout_s
    else:
        with pytest.raises(ValueError, match="motor_timeout_s 0.006 s would disable the motors between two"):
            RobotConfig.model_validate(data)

