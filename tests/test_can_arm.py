"""CanArm on simulated Damiao motors (python-can virtual bus): control, safety and every fault ends safe."""

import os
import signal
import sys
import time

import can
import numpy as np
import pytest

from drivers.arm.can_arm import CanArm
from drivers.arm.damiao import MotorLimits, Status
from drivers.arm.motion import move_to_joints
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from drivers.errors import ArmError, CanBusError
from sim_fallback.can_motors import MotorFaults
from sim_fallback.devices import sim_can_arm

PANDA = load_robot_config("panda_sim")
CONFIG = PANDA.model_copy(update={"control_rate_hz": 500.0})
LIMITS = MotionLimits(0.5, 2.0, 20.0)
RELAXED = CONFIG.model_copy(update={"watchdog": CONFIG.watchdog.model_copy(  # realtime tests on a loaded machine
    update={"max_late_cycles": 200.0, "feedback_timeout_s": 0.5})})
TRACK_TOL = 3e-3  # tau = 0 is not representable in 12 bits: half a step (TMAX / 4095) over kp offsets the hold


def _arm(config=CONFIG, **kwargs):
    return sim_can_arm(config, **kwargs)


def _all_disabled(motors) -> bool:
    return not any(m.enabled for m in motors.motors)


def _eventually_disabled(motors, timeout_s: float = 2.0) -> bool:
    """Realtime: the motors' own thread handles the disable frames a moment later."""
    end = time.perf_counter() + timeout_s
    while not _all_disabled(motors) and time.perf_counter() < end:
        time.sleep(0.01)
    return _all_disabled(motors)


def _run(arm, cycles: int) -> None:
    for _ in range(cycles):
        arm.sync()


def test_connect_reads_limits_from_the_motors_and_enables():
    arm, motors = _arm()
    motors.motor("panda_joint1").limits = MotorLimits(12.0, 20.0, 150.0)
    with arm:
        assert isinstance(arm, CanArm) and all(m.enabled for m in motors.motors)
        assert arm.joints[0].limits == MotorLimits(12.0, 20.0, 150.0)
        np.testing.assert_allclose(arm.state().q, CONFIG.q_ready, atol=1e-3)
        assert arm.state().gripper_width_m == pytest.approx(0.08, abs=1e-3)
        report = arm.motor_report()
        assert len(report) == 8 and report[0]["status"] == "enabled" and report[0]["t_max"] == 150.0
    assert _all_disabled(motors)


def test_one_mit_command_per_motor_per_cycle_and_tracking():
    arm, motors = _arm()
    with arm:
        before = [m.mit_frames for m in motors.motors]
        _run(arm, 50)
        assert [m.mit_frames - b for m, b in zip(motors.motors, before, strict=True)] == [50] * 8
        goal = arm.state().q + np.array([0.3, -0.2, 0.2, 0.3, 0.3, -0.3, 0.4])
        assert move_to_joints(arm, goal, LIMITS)
        _run(arm, 300)
        np.testing.assert_allclose(arm.state().q, goal, atol=TRACK_TOL)


def test_direction_and_zero_offset_map_joint_to_motor():
    joints = list(CONFIG.joints)
    joints[0] = joints[0].model_copy(update={"direction": -1, "zero_offset": 0.5})
    arm, motors = _arm(CONFIG.model_copy(update={"joints": joints}))
    with arm:
        q = arm.state().q
        assert q[0] == pytest.approx(CONFIG.q_ready[0], abs=1e-3)
        assert motors.motor("panda_joint1").q == pytest.approx(-(CONFIG.q_ready[0] - 0.5), abs=1e-3)
        assert move_to_joints(arm, q + np.r_[0.2, np.zeros(6)], LIMITS)
        _run(arm, 300)
        assert arm.state().q[0] == pytest.approx(q[0] + 0.2, abs=TRACK_TOL)
        assert motors.motor("panda_joint1").q == pytest.approx(-(q[0] + 0.2 - 0.5), abs=TRACK_TOL)


def test_gripper_moves_to_the_commanded_width():
    arm, _ = _arm()
    with arm:
        arm.set_gripper(0.03, force_n=100.0)
        _run(arm, 1500)
        assert arm.state().gripper_width_m == pytest.approx(0.03, abs=1e-3)


def test_compliant_gains_reach_the_motors():
    arm, motors = _arm()
    with arm:
        _run(arm, 2)
        assert motors.motor("panda_joint2").command[2] == pytest.approx(CONFIG.joints[1].kp, abs=0.2)
        arm.set_compliance(True)
        _run(arm, 2)
        assert motors.motor("panda_joint2").command[2] == pytest.approx(CONFIG.joints[1].kp_compliant, abs=0.2)
        assert motors.motor("panda_joint2").command[3] == pytest.approx(CONFIG.joints[1].kd_compliant, abs=0.01)


def test_safety_limit_disables_the_motors_and_names_the_joint():
    arm, motors = _arm()
    with arm:
        q = arm.state().q
        q[3] = 10.0
        with pytest.raises(ArmError, match="panda_joint4 position 10.0000 rad is above its limit"):
            arm.command(q)
        assert _all_disabled(motors)
        with pytest.raises(ArmError, match="not enabled"):
            arm.command(arm.state().q)


def test_config_above_the_motor_torque_limit_is_refused_at_connect():
    arm, motors = _arm()
    motors.motor("panda_joint5").limits = MotorLimits(12.5, 8.0, 5.0)
    with pytest.raises(ArmError, match=r"panda_joint5 .*tau_max 12.0 N m exceeds the motor's TMAX 5.0"):
        arm.connect()
    assert _all_disabled(motors)
    arm.disconnect()


def test_start_outside_the_joint_limits_is_refused():
    arm, motors = _arm()
    motors.motor("panda_joint4").q = 1.0  # Panda joint 4 is limited to [-3.07, -0.07]
    with pytest.raises(ArmError, match="panda_joint4 .*outside its limits.*zero_offset"):
        arm.connect()
    assert _all_disabled(motors)
    arm.disconnect()


@pytest.mark.parametrize(("status", "words"), [
    (Status.OVER_CURRENT, "over-current"), (Status.COIL_OVER_TEMPERATURE, "coil-over-temperature"),
    (Status.UNDER_VOLTAGE, "under-voltage"),
])
def test_status_fault_mid_motion_ends_safe_with_the_joint_and_fault(status, words):
    arm, motors = _arm()
    with arm:
        goal = arm.state().q + 0.3
        calls = []

        def inject(_state, t):
            calls.append(t)
            if len(calls) == 20:
                motors.motor("panda_joint3").faults.status = status

        with pytest.raises(ArmError, match=f"panda_joint3 .*reports {words}.*motors disabled"):
            move_to_joints(arm, goal, LIMITS, inject)
        assert _all_disabled(motors) and arm.fault is not None


def test_motor_that_stops_answering_trips_the_watchdog():
    arm, motors = _arm()
    with arm:
        _run(arm, 10)
        motors.motor("panda_joint6").faults.silent = True
        with pytest.raises(ArmError, match=r"watchdog: joint panda_joint6 .*no valid feedback"):
            _run(arm, 50)
        assert not any(m.enabled for m in motors.motors if m is not motors.motor("panda_joint6"))


def test_some_dropped_frames_are_tolerated_all_dropped_are_not():
    arm, motors = _arm(faults={"panda_joint2": MotorFaults(drop_every=2)})
    with arm:
        _run(arm, 200)  # every second reply lost: feedback never older than one cycle
        motors.motor("panda_joint2").faults.drop_rate = 1.0
        with pytest.raises(ArmError, match="panda_joint2"):
            _run(arm, 50)
    assert _all_disabled(motors)


def test_delayed_frames_within_the_timeout_pass_beyond_it_trip():
    timeout = CONFIG.watchdog.feedback_timeout_s
    arm, motors = _arm()
    with arm:
        motors.motor("panda_joint1").faults.delay_s = 0.5 * timeout
        _run(arm, 100)
        motors.motor("panda_joint1").faults.delay_s = 3 * timeout
        with pytest.raises(ArmError, match="watchdog: joint panda_joint1"):
            _run(arm, 100)
    assert _all_disabled(motors)


def test_malformed_frames_are_ignored():
    arm, motors = _arm()
    with arm:
        intruder = can.Bus(interface="virtual", channel=arm.bus.channel)
        try:
            for data in (bytes(3), bytes([0x71] + [0] * 7), b"\xff" * 8):
                intruder.send(can.Message(arbitration_id=0x13, data=data, is_extended_id=False))
            _run(arm, 20)
            assert arm.fault is None and arm.joints[2].malformed >= 2
        finally:
            intruder.shutdown()


def test_bus_off_ends_with_a_bus_error():
    arm, motors = _arm()
    with arm:
        _run(arm, 5)
        motors.inject_bus_off()
        with pytest.raises(CanBusError, match="bus-off.*terminations"):
            _run(arm, 5)
        assert isinstance(arm.fault, CanBusError)


def test_error_passive_ends_with_a_bus_error():
    arm, motors = _arm()
    with arm:
        motors.inject_error_passive()
        with pytest.raises(CanBusError, match="error-passive"):
            _run(arm, 5)
    assert _all_disabled(motors)


def test_torque_above_the_limit_is_a_fault():
    joints = [j.model_copy(update={"tau_max": 0.05}) if j.name == "panda_joint1" else j for j in CONFIG.joints]
    arm, motors = _arm(CONFIG.model_copy(update={"joints": joints}))
    with arm:
        with pytest.raises(ArmError, match=r"safety stop: joint panda_joint1 .*torque .* exceeds"):
            move_to_joints(arm, arm.state().q + np.r_[0.5, np.zeros(6)], LIMITS)
    assert _all_disabled(motors)


def test_stop_damps_then_disables_and_is_idempotent():
    arm, motors = _arm()
    arm.connect()
    arm.stop()
    assert _all_disabled(motors)
    assert motors.motor("panda_joint1").mit_frames >= CONFIG.watchdog.stop_damping_s * CONFIG.control_rate_hz
    arm.stop()
    arm.connect()  # enabling again after a stop works
    assert all(m.enabled for m in motors.motors)
    arm.disconnect()
    arm.disconnect()
    assert _all_disabled(motors)


@pytest.mark.parametrize(("sig", "raised"), [(signal.SIGTERM, SystemExit), (signal.SIGINT, KeyboardInterrupt)])
def test_sigterm_and_ctrl_c_disable_the_motors(sig, raised):
    before = signal.getsignal(sig)
    arm, motors = _arm(RELAXED, lockstep=False)
    with arm:
        with pytest.raises(raised):
            os.kill(os.getpid(), sig)
            time.sleep(1.0)  # the handler runs here
        assert arm.fault is not None and sig.name in str(arm.fault)
        assert _eventually_disabled(motors)
    assert signal.getsignal(sig) is before


def test_realtime_loop_runs_and_holds():
    arm, motors = _arm(RELAXED, lockstep=False)
    with arm:
        q0 = arm.state().q
        time.sleep(0.3)
        _run(arm, 5)
        stats = arm.stats.summary(arm.control_period_s)
        assert stats["cycles"] > 20 and arm.fault is None
        np.testing.assert_allclose(arm.state().q, q0, atol=TRACK_TOL)
    assert _eventually_disabled(motors)


def test_realtime_watchdog_trips_on_a_missed_cycle():
    watchdog = CONFIG.watchdog.model_copy(update={"max_late_cycles": 5.0, "feedback_timeout_s": 5.0,
                                                  "motor_timeout_s": 1.0})  # the late cycle trips first
    arm, motors = _arm(CONFIG.model_copy(update={"watchdog": watchdog}), lockstep=False)
    old = sys.getswitchinterval()
    with arm:
        sys.setswitchinterval(0.2)  # the control thread waits for this thread's busy loop: cycles are missed
        try:
            end = time.perf_counter() + 0.5
            while time.perf_counter() < end:
                pass
        finally:
            sys.setswitchinterval(old)
        time.sleep(0.1)
        assert arm.fault is not None and "watchdog: control cycle started" in str(arm.fault)
        assert _eventually_disabled(motors)
        with pytest.raises(ArmError, match="late"):
            arm.sync()


def test_gravity_compensation_feeds_forward_the_urdf_gravity_torque():
    import pybullet as pb
    import pybullet_data

    joints = [CONFIG.joints[0].model_copy(update={"direction": -1}), *CONFIG.joints[1:]]
    arm, motors = _arm(CONFIG.model_copy(update={"gravity_compensation": True, "joints": joints}))
    with arm:
        q = arm.state().q
        expected = arm.gravity_torques(q)
        client = pb.connect(pb.DIRECT)
        try:  # the same URDF in PyBullet: inverse dynamics at rest is the gravity torque
            pb.setGravity(0, 0, -9.81, physicsClientId=client)
            robot = pb.loadURDF(f"{pybullet_data.getDataPath()}/franka_panda/panda.urdf", useFixedBase=True,
                                flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
            full = [*q.tolist(), 0.0, 0.0]
            reference = pb.calculateInverseDynamics(robot, full, [0.0] * 9, [0.0] * 9, physicsClientId=client)[:7]
        finally:
            pb.disconnect(client)
        np.testing.assert_allclose(expected, reference, atol=1e-3)
        assert np.abs(expected).max() > 5.0
        _run(arm, 1)
        sent = np.array([m.command[4] for m in motors.motors[:7]])
        sent[0] *= -1  # motor side -> joint side
        np.testing.assert_allclose(sent, expected, atol=2 * 200.0 / 4095)  # one 12-bit step over +-TMAX
