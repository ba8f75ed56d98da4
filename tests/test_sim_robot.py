"""The simulation runs the user's arm: a robot config's arm stands in the simulated world (`--arm sim` and `sim-can`
with `--robot openarm`), its hinged fingers grip as its config says, the rig's self-filter and kinematics are its
own, and an episode runs with it to a named end."""

import json

import numpy as np
import pytest

from deploy.rig import RigSpec, open_rig
from drivers.arm.robot_config import CONFIG_DIR, load_robot_config
from sim_fallback.devices import open_sim_arm, sim_can_arm
from sim_fallback.scenario import Scenario
from sim_fallback.start import Q_START
from sim_fallback.world import SimWorld
from tests.cli_run import run

OPENARM = load_robot_config("openarm")


def test_the_world_stands_the_configs_arm_at_its_start_with_the_scenarios_jitter():
    scenario = Scenario.make("drawer", 4)
    with SimWorld(scenario, robot=OPENARM.robot_spec()) as world:
        assert set(OPENARM.joint_names) <= set(world.robot_joints) and "panda_joint1" not in world.robot_joints
        arm = open_sim_arm("", OPENARM, world=world)
        state = arm.state()
        expected = np.array(OPENARM.q_ready) + (np.array(scenario.q_start) - Q_START)
        assert np.allclose(state.q, expected, atol=1e-6)
        assert state.gripper_width_m == pytest.approx(OPENARM.gripper.max_width_m, abs=1e-6)


def test_the_hinged_fingers_close_to_the_commanded_opening():
    with SimWorld(Scenario.make("drawer", 0), robot=OPENARM.robot_spec()) as world:
        arm = open_sim_arm("", OPENARM, world=world)
        q = arm.state().q
        arm.set_gripper(0.05, 40.0)
        for _ in range(240):
            arm.sync()
        state = arm.state()
        assert state.gripper_width_m == pytest.approx(0.05, abs=0.003)
        assert np.abs(state.q - q).max() < 0.01  # the arm holds still meanwhile


def test_the_panda_world_is_unchanged_by_its_config():
    """The panda_sim config's arm is the world's default Panda, started where the scenarios always started it."""
    scenario = Scenario.make("door", 2)
    spec = load_robot_config("panda_sim").robot_spec()
    with SimWorld(scenario) as default, SimWorld(scenario, robot=spec) as configured:
        for world in (default, configured):
            arm = open_sim_arm("", load_robot_config("panda_sim"), world=world)
            assert np.allclose(arm.state().q, scenario.q_start, atol=1e-9)
            assert arm.state().gripper_width_m == pytest.approx(0.08)


def test_a_rig_with_robot_openarm_is_the_openarms_everywhere():
    spec = RigSpec(camera="sim", arm="sim-can", robot=CONFIG_DIR / "openarm.toml", segmenter="rgbd",
                   camera_options={"width": 160, "height": 120})
    with open_rig(spec) as rig:
        assert rig.world.robot_spec.arm_joints == tuple(OPENARM.joint_names) == tuple(rig.arm.joint_names)
        assert rig.kin.tool_frame == "openarm_right_tcp"
        assert rig.self_filter().body.model.existJointName("openarm_right_finger_joint1")  # its own pixels
        with rig.arm:
            q = rig.arm.state().q
            assert np.allclose(q, rig.world.robot_spec.start + (np.array(rig.world.scenario.q_start) - Q_START),
                               atol=0.01)


def test_sim_can_drives_the_openarm_in_the_world():
    with SimWorld(Scenario.make("drawer", 1), robot=OPENARM.robot_spec()) as world:
        arm, motors = sim_can_arm(OPENARM, world)
        with arm:
            q0 = arm.state().q
            target = q0.copy()
            target[3] -= 0.05
            for k in range(1, 101):
                arm.command(q0 + (target - q0) * k / 100)
                arm.sync()
            for _ in range(60):
                arm.sync()
            assert np.abs(arm.state().q - target).max() < 0.01
        assert not any(m.enabled for m in motors.motors)


def test_an_episode_with_robot_openarm_ends_with_a_named_reason(capsys, tmp_path):
    code, out, err = run(capsys, "open-drawer", "--arm", "sim", "--robot", "openarm", "--seed", "3", "--run-dir",
                         tmp_path / "run", "--json")
    data = json.loads(out)
    assert "Traceback" not in err and code in (0, 1)
    assert data["success"] or data["stop_reason"] in ("ik infeasible", "no clear path", "blocked", "timeout",
                                                     "tracking lost", "slipped", "arm error")
    if data["stop_reason"] == "ik infeasible":
        assert "out of reach" in data["message"] or "joint limits" in data["message"]


def test_the_openarm_plans_a_drawer_pull_within_its_reach():
    """The grasp planner on OpenArm's layout (its shoulder is no Panda's column): a handle 0.5 m in front at 0.5 m
    height, pulled 0.3 m straight back, is planned clear of the joint limits; one at the box world's usual 0.8 m
    height is out of its reach (the shoulder stands at 0.7 m)."""
    from deploy.control.grasp import pregrasp_configuration
    from drivers.arm.grasping import GRASP_DEPTH_M, GRASP_PITCH_RAD
    from drivers.arm.grasping import grasp_pose as bar_grasp_pose
    from drivers.errors import IKError

    kin = OPENARM.kinematics()
    limits = OPENARM.safety_limits(kin)

    def plan(height_m: float) -> np.ndarray:
        T = bar_grasp_pose(np.array([0.5, 0.0, height_m]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]),
                           GRASP_DEPTH_M, GRASP_PITCH_RAD)
        pull = [T.copy() for _ in range(6)]
        for k, P in enumerate(pull):
            P[0, 3] -= 0.05 * (k + 1)
        return pregrasp_configuration(kin, np.array(OPENARM.q_ready), T, [pull], 0.1)

    q = plan(0.5)
    assert np.all(q > limits.q_min) and np.all(q < limits.q_max)
    with pytest.raises(IKError, match="out of reach"):
        plan(0.85)


def test_the_openarm_grasps_and_pulls_a_drawer_it_reaches():
    """Parked by its own reach (openarm.toml `[reach]`), the OpenArm grasps the box-world drawer of test seed 0 and
    pulls it open through the vendor's kinematics, the hinged gripper and the controller (the world's truth scores
    it)."""
    from deploy.bench.open import simulate_episode

    result = simulate_episode("drawer", 0, "test", robot=CONFIG_DIR / "openarm.toml", world="box")
    assert result["true_opened_m"] > 0.1, result["message"]
