"""Robot configs: the examples load and match their URDFs; bad configs are one clear error; the arm factory."""

import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from drivers.arm.ideal import IdealArm
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import CONFIG_DIR, PANDA_SIM_CONFIG, load_robot_config, shipped_robot_configs
from drivers.errors import ArmError

EXAMPLES = sorted(CONFIG_DIR.glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_examples_load_and_match_their_urdf(path):
    config = load_robot_config(path)
    kin = config.kinematics()
    assert kin.joint_names == config.joint_names and len(config.joints) in (6, 7)
    limits = config.safety_limits(kin)
    q = np.array(config.q_ready)
    assert np.all(q > limits.q_min) and np.all(q < limits.q_max)
    tool = kin.fk(q)[:3, 3]
    assert np.all(tool > limits.workspace_min) and np.all(tool < limits.workspace_max)
    for j in config.joints:  # the example limits fit the motors' factory ranges
        assert j.tau_max <= j.default_limits.t_max


def test_config_limits_narrow_the_urdf_limits(tmp_path):
    config = load_robot_config("damiao_6dof")
    limits = config.safety_limits(config.kinematics())
    assert limits.v_max[0] == 2.0  # the URDF says 3.14
    joints = [config.joints[0].model_copy(update={"q_min": -1.0, "q_max": 1.0}), *config.joints[1:]]
    narrowed = config.model_copy(update={"joints": joints}).safety_limits(config.kinematics())
    assert (narrowed.q_min[0], narrowed.q_max[0]) == (-1.0, 1.0)


@pytest.mark.parametrize(("edit", "words"), [
    (lambda t: t.replace('motor = "DM8009"', 'motor = "DM9999"', 1), "joints.0: Value error, unknown motor model"),
    (lambda t: t.replace("can_id = 2", "can_id = 1", 1), "share a can_id"),
    (lambda t: t.replace("q_ready = [0.0, -0.3,", "q_ready = [-0.3,", 1), "q_ready has 5 values for 6 joints"),
    (lambda t: t.replace("tau_max = 40.0", "tau_max = -1.0", 1), "joints.0.tau_max"),
    (lambda t: t.replace("[can]", "[can]\nspeed = 3", 1), "can.speed: Extra inputs"),
    (lambda t: t + "\n[[joints\n", "not valid TOML"),
])
def test_bad_configs_name_the_field(tmp_path, edit, words):
    path = tmp_path / "arm.toml"
    path.write_text(edit((CONFIG_DIR / "damiao_6dof.toml").read_text()))
    with pytest.raises(ArmError, match=words.replace("(", r"\(")):
        load_robot_config(path)


def test_joints_that_do_not_match_the_urdf(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text((CONFIG_DIR / "damiao_6dof.toml").read_text().replace('name = "joint2"', 'name = "elbow"'))
    with pytest.raises(ArmError, match="do not match the URDF's movable joints"):
        load_robot_config(path).kinematics()


def test_missing_config():
    with pytest.raises(ArmError, match="not found"):
        load_robot_config("configs/robots/nope.toml")
    with pytest.raises(ArmError, match=r"not found: give the path of a TOML file or a shipped config's name "
                                       r"\(damiao_6dof, openarm, panda_sim\)"):
        load_robot_config("nope")


def test_shipped_configs_load_by_name_and_ship_in_the_wheel(tmp_path):
    assert shipped_robot_configs() == ["damiao_6dof", "openarm", "panda_sim"]
    assert load_robot_config("panda_sim").source == PANDA_SIM_CONFIG == CONFIG_DIR / "panda_sim.toml"
    user = tmp_path / "panda_sim"  # a path is read as given, even one named like a shipped config
    user.write_text(PANDA_SIM_CONFIG.read_text().replace('name = "panda-sim"', 'name = "mine"'))
    assert load_robot_config(user).name == "mine"
    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path / "dist"), str(root)], check=True, capture_output=True, timeout=300)
    (wheel,) = (tmp_path / "dist").glob("axisloop-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert {"drivers/arm/configs/panda_sim.toml", "drivers/arm/configs/damiao_6dof.toml",
            "drivers/arm/configs/openarm.toml", "drivers/arm/openarm/openarm.urdf", "drivers/arm/openarm/LICENSE",
            "drivers/arm/openarm/NOTICE", "drivers/arm/openarm/meshes/link1.stl"} <= set(names)


def test_registry_builds_every_arm_kind_and_refuses_unknown():
    config = load_robot_config("panda_sim")
    ideal = open_arm("ideal", config)
    assert isinstance(ideal, IdealArm) and ideal.control_period_s == pytest.approx(1 / 240)
    np.testing.assert_allclose(ideal.state().q, config.q_ready)
    with pytest.raises(ArmError, match="where no real motor is"):  # the example's bus is virtual: not for `can`
        open_arm("can", config)
    sim_can = open_arm("sim-can", config)  # registered by sim_fallback's plug-in: simulated motors answer
    with sim_can:
        np.testing.assert_allclose(sim_can.state().q, config.q_ready, atol=1e-3)
    with pytest.raises(ArmError, match="needs a simulated world"):
        open_arm("sim", config)
    with pytest.raises(ArmError, match="unknown arm 'robot': choose one of can, ideal, sim, sim-can"):
        open_arm("robot", config)
