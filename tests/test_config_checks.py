"""Robot and run configs refused at load with one line naming the file, the field and the fix."""

import pytest
from cli_run import one_line, run

from deploy.config import load_config
from deploy.errors import ConfigError
from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import CONFIG_DIR, load_robot_config
from drivers.errors import ArmError

EXAMPLE = (CONFIG_DIR / "damiao_6dof.toml").read_text()


def _robot(tmp_path, *edits: tuple[str, str], extra: str = "") -> str:
    """The damiao_6dof example with each (old, new) replaced once, written to a file; its path."""
    text = EXAMPLE
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "arm.toml"
    path.write_text(text + extra)
    return path


def _refused(path, *words: str) -> str:
    """The ArmError loading `path` and building its kinematics gives; it names the file and every word."""
    with pytest.raises(ArmError) as err:
        load_robot_config(path).kinematics()
    text = str(err.value)
    assert "\n" not in text and all(w in text for w in (*words, str(path))), text
    return text


def test_master_id_equal_to_another_motors_can_id(tmp_path):
    _refused(_robot(tmp_path, ("master_id = 0x13", "master_id = 1")),
             "joint joint3's master_id 0x1", "joint joint1's can_id")


def test_gripper_width_in_mm(tmp_path):
    _refused(_robot(tmp_path, ("max_width_m = 0.08", "max_width_m = 80")), "gripper.max_width_m", "0.3")


@pytest.mark.parametrize(("q_ready", "words"), [
    ("[0.0, -17.0, -69.0, 0.0, 86.0, 0.0]", ("q_ready of joint joint2", "outside its limits")),  # degrees
    ("[0.0, -0.3, -1.2, 0.0, 1.5, 10.0]", ("q_ready of joint joint6",)),  # beyond the URDF's +-2 pi
])
def test_q_ready_outside_the_urdf_limits(tmp_path, q_ready, words):
    _refused(_robot(tmp_path, ("q_ready = [0.0, -0.3, -1.2, 0.0, 1.5, 0.0]", f"q_ready = {q_ready}")), *words)


def test_q_ready_outside_the_config_limits(tmp_path):
    _refused(_robot(tmp_path, ("v_max = 2.0\ntau_max = 40.0", "q_max = -0.5\nv_max = 2.0\ntau_max = 40.0")),
             "q_ready of joint joint1", "q_max -0.5")


@pytest.mark.parametrize("field", ["v_max", "a_max", "j_max"])
def test_tiny_motion_limits(tmp_path, field):
    path = _robot(tmp_path, ("v_max = 2.0\ntau_max = 40.0", f"tau_max = 40.0\n{field} = 1e-9"))
    _refused(path, f"joints.0.{field}: Input should be greater than or equal to")


def test_urdf_that_is_not_a_urdf(tmp_path):
    (tmp_path / "arm.urdf").write_text('name = "not xml"\n')
    (tmp_path / "other.urdf").write_text("<sdf></sdf>\n")
    for name in ("arm.urdf", "other.urdf"):
        with pytest.raises(ArmError, match=f"robot URDF .*{name} .*: give the path of the arm's .urdf file"):
            Kinematics.from_urdf(tmp_path / name, "link6")


def test_empty_urdf_names_the_directory(tmp_path):
    with pytest.raises(ArmError, match="is a directory"):
        load_robot_config(_robot(tmp_path, ('urdf = "pybullet_data:xarm/xarm6_robot.urdf"', 'urdf = ""'))).kinematics()


def test_config_range_outside_the_urdfs(tmp_path):
    path = _robot(tmp_path, ("q_ready = [0.0, -0.3,", "q_ready = [0.0, 5.5,"),
                  ("direction = -1", "direction = -1\nq_min = 5.0\nq_max = 6.0"))
    _refused(path, "joint joint2's range [5.0, 6.0]", "URDF's [-2.059, 2.094]")


def test_errors_name_the_file_and_unknown_keys(tmp_path):
    _refused(_robot(tmp_path, ('name = "joint2"', 'name = "elbow"')), "do not match the URDF")
    text = _refused(_robot(tmp_path, ("tau_max = 40.0", "tau_mx = 40.0")), "joints.0.tau_max: Field required")
    assert "joints.0.tau_mx: Extra inputs are not permitted" in text


def test_byte_order_mark(tmp_path):
    robot = _robot(tmp_path)
    robot.write_text(robot.read_text(), encoding="utf-8-sig")
    assert load_robot_config(robot).name == "damiao-6dof"
    run_config = tmp_path / "run.toml"
    run_config.write_text("[filter]\neps = 3\n", encoding="utf-8-sig")
    assert load_config(run_config).filter.eps == 3


def test_config_directory(tmp_path):
    with pytest.raises(ConfigError, match=f"config file {tmp_path} is a directory"):
        load_config(tmp_path)


def test_axis_estimate_names_the_option(capsys, tmp_path):
    run_config = tmp_path / "run.toml"
    run_config.write_text("[filter]\neps = 3\n")
    for args in (("--config", run_config, "--filter-eps", 0), ("--filter-radius-m", 50)):
        code, _, err = run(capsys, "axis", "estimate", tmp_path, *args)
        assert code == 2 and f"invalid value for {args[-2]}" in one_line(err), err
