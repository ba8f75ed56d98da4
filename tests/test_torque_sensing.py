"""Joint torques as a Damiao motor measures them (sim_fallback/torque_sensing.py): the feedback frame's 12-bit grid,
white noise, a per-joint offset and a slowly drifting bias of the sizes the model states, one seed per episode; and
the simulated arms (`sim`, `sim-can`) reporting them."""

import numpy as np
import pybullet as pb
import pytest

from drivers.arm.damiao import MODELS, MotorLimits, Status, pack_feedback, unpack_feedback
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import load_robot_config
from sim_fallback.arm import SimArm
from sim_fallback.devices import PAD_FRICTION_RANGE, episode_signals, sim_can_arm
from sim_fallback.scenario import Scenario
from sim_fallback.torque_sensing import TorqueErrors, TorqueSensing
from sim_fallback.world import SimWorld

PANDA = load_robot_config("panda_sim")
T_MAX = np.array([MODELS["DM10010L"].t_max, MODELS["DM4340"].t_max, MODELS["DM4310"].t_max])


def test_readings_lie_on_the_feedback_frames_grid_and_clip_at_tmax():
    sensing = TorqueSensing(T_MAX, seed=1, errors=TorqueErrors.none())
    true = np.array([12.34, -3.21, 0.123])
    reading = sensing.measure(true, 0.0)
    for tau, t_max, value in zip(true, T_MAX, reading, strict=True):
        limits = MotorLimits(12.5, 30.0, t_max)
        framed = unpack_feedback(pack_feedback(1, Status.ENABLED, 0.0, 0.0, tau, 30, 30, limits), limits).tau
        assert value == pytest.approx(framed, abs=1e-9)  # what the motor's frame would carry
    assert np.all(np.abs(reading - true) <= sensing.step_n_m / 2 + 1e-12)
    np.testing.assert_allclose(sensing.measure(true * 0 + 1e4, 1.0), T_MAX)
    np.testing.assert_allclose(sensing.measure(-true * 0 - 1e4, 2.0), -T_MAX)


def test_noise_offset_and_bias_have_the_stated_sizes():
    errors = TorqueErrors()
    t_max = np.full(400, 200.0)  # many joints of one motor model: the spreads over joints
    sensing = TorqueSensing(t_max, seed=3, errors=errors)
    offset, bias0 = sensing.offset.copy(), sensing.bias.copy()
    assert np.std(offset) == pytest.approx(errors.offset_share * 200.0, rel=0.1)
    assert np.std(bias0) == pytest.approx(errors.bias_share * 200.0, rel=0.1)
    readings = np.array([sensing.measure(np.zeros(400), 0.0) for _ in range(50)])  # one instant: bias fixed
    noise = readings - readings.mean(axis=0)
    assert np.std(noise) == pytest.approx(errors.noise_share * 200.0, rel=0.1)
    np.testing.assert_allclose(readings.mean(axis=0), offset + bias0, atol=0.3)
    np.testing.assert_array_equal(sensing.offset, offset)  # the offset stays for the episode


def test_the_bias_drifts_slowly_and_keeps_its_spread():
    errors = TorqueErrors()
    sensing = TorqueSensing(np.full(400, 200.0), seed=4, errors=errors)
    history = []
    for t in np.arange(0.0, 3000.0, 2.0):
        sensing.measure(np.zeros(400), float(t))
        history.append(sensing.bias.copy())
    bias = np.array(history)
    assert np.std(bias) == pytest.approx(errors.bias_share * 200.0, rel=0.15)

    def correlation(lag: int) -> float:
        return float(np.corrcoef(bias[:-lag].ravel(), bias[lag:].ravel())[0, 1])

    assert correlation(1) == pytest.approx(np.exp(-2.0 / errors.bias_time_s), abs=0.01)  # 2 s apart
    assert correlation(180) == pytest.approx(np.exp(-360.0 / errors.bias_time_s), abs=0.1)  # 3 correlation times


def test_a_seed_repeats_an_episodes_readings_another_seed_does_not():
    def readings(seed):
        sensing = TorqueSensing(T_MAX, seed=seed)
        return np.array([sensing.measure(np.ones(3), t) for t in np.arange(0.0, 1.0, 0.1)])

    np.testing.assert_array_equal(readings(7), readings(7))
    assert not np.array_equal(readings(7), readings(8))
    a, b = episode_signals(PANDA, 5), episode_signals(PANDA, 5)
    assert a.pad_friction == b.pad_friction and np.array_equal(a.torque_sensing.offset, b.torque_sensing.offset)
    frictions = [episode_signals(PANDA, s).pad_friction for s in range(200)]
    assert PAD_FRICTION_RANGE[0] <= min(frictions) < 0.45 and 0.75 < max(frictions) <= PAD_FRICTION_RANGE[1]


def _raw_torques(world) -> np.ndarray:
    joints = [world.robot_joints[n] for n in world.robot_spec.arm_joints]
    return np.array([s[3] for s in pb.getJointStates(world.robot_id, joints, physicsClientId=world.client)])


def test_the_sim_arm_reports_measured_torques_one_reading_per_physics_step():
    with SimWorld(Scenario.make("drawer", 2, "test")) as world:
        arm = open_arm("sim", PANDA, world=world)
        sensing = arm.torque_sensing
        assert isinstance(arm, SimArm) and sensing is not None
        assert arm.pad_friction == episode_signals(PANDA, 2).pad_friction
        bias_start, errors = sensing.bias.copy(), []
        for _ in range(60):
            arm.sync()
            first, again = arm.state().tau, arm.state().tau
            np.testing.assert_array_equal(first, again)  # the same reading until the next step
            on_grid = (first + sensing.t_max) / sensing.step_n_m
            np.testing.assert_allclose(on_grid, np.round(on_grid), atol=1e-6)
            errors.append(first - _raw_torques(world))
        errors = np.array(errors)
        expected = sensing.offset + (bias_start + sensing.bias) / 2
        assert np.all(np.abs(errors.mean(axis=0) - expected) < 0.002 * sensing.t_max), (errors.mean(axis=0), expected)
        assert np.all(errors.std(axis=0) > 0.5 * TorqueErrors().noise_share * sensing.t_max)


def test_the_sim_can_arms_feedback_frames_carry_the_measured_torques():
    with SimWorld(Scenario.make("drawer", 2, "test")) as world:
        arm, motors = sim_can_arm(PANDA, world)
        sensing = motors.backend.arm.torque_sensing
        np.testing.assert_array_equal(sensing.offset, episode_signals(PANDA, 2).torque_sensing.offset)
        with arm:
            bias_start, errors = sensing.bias.copy(), []
            for _ in range(60):
                arm.sync()
                errors.append(arm.state().tau - _raw_torques(world))
        expected = sensing.offset + (bias_start + sensing.bias) / 2
        assert np.all(np.abs(np.mean(errors, axis=0) - expected) < 0.002 * sensing.t_max), (errors, expected)
