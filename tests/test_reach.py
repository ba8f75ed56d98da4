"""An arm's reach (robot config `[reach]`) decides where simulated scenes put the grip of the part to open."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config
from drivers.arm.robots import PANDA_REACH, Reach
from sim_fallback.kitchen_scenario import arm_grasps
from sim_fallback.scenario import make_scenario
from sim_fallback.world import SimWorld

LOW = Reach(drawer_distance_m=(0.62, 0.66), drawer_height_m=(0.5, 0.56), door_distance_m=(0.62, 0.66),
            door_height_m=(0.5, 0.56))  # an arm that grips lower than the Panda, and farther


def test_a_robot_config_without_reach_has_the_pandas_and_one_with_it_its_own(tmp_path):
    assert load_robot_config(PANDA_SIM_CONFIG).robot_spec().reach == PANDA_REACH
    path = tmp_path / "low.toml"

    def reach_with(lines: str) -> Reach:
        path.write_text(PANDA_SIM_CONFIG.read_text().replace("[reach]\n", f"[reach]\n{lines}\n"))
        return load_robot_config(path).robot_spec().reach

    reach = reach_with("drawer_height_m = [0.42, 0.46]")
    assert reach.drawer_height_m == (0.42, 0.46) and reach.door_height_m == PANDA_REACH.door_height_m
    with pytest.raises(Exception, match="reach.drawer_height_m"):
        reach_with("drawer_height_m = [0.6, 0.4]")
    bare = "\n".join(line for line in PANDA_SIM_CONFIG.read_text().splitlines() if not line.startswith("low_"))
    path.write_text(bare)  # no bands from above: the usual ones are the Panda's, none from above
    reach = load_robot_config(path).robot_spec().reach
    assert reach.drawer_height_m == PANDA_REACH.drawer_height_m and reach.from_above("drawer") is None
    path.write_text(bare.replace("[reach]\n", "[reach]\nlow_door_height_m = [0.3, 0.5]\n"))
    with pytest.raises(Exception, match="low_door_distance_m and low_door_height_m come together"):
        load_robot_config(path)
    low = PANDA_REACH.from_above("drawer")
    assert low.drawer_height_m == PANDA_REACH.low_drawer_height_m and low.door_height_m == PANDA_REACH.door_height_m


@pytest.mark.parametrize("world", ["kitchen", "box"])
def test_scenes_put_the_grip_in_the_arms_reach(world):
    """The same seeds, parked for the Panda and for an arm that reaches lower and farther: each grip lies in its
    arm's bands (in the box world the distance is the front's centre's, and the handle stands out of it)."""
    for seed in range(3):
        for reach in (PANDA_REACH, LOW):
            with SimWorld(make_scenario(world, "drawer", seed, "test", reach=reach)) as sim:
                grip = sim.target_handle()[0]
            distance, height = float(np.hypot(*grip[:2])), float(grip[2])
            if world == "kitchen":
                assert reach.distance("drawer")[0] - 1e-6 <= distance <= reach.distance("drawer")[1] + 1e-6
                assert reach.height("drawer")[0] - 1e-6 <= height <= reach.height("drawer")[1] + 1e-6
            else:
                assert reach.distance("drawer")[0] - 0.1 <= distance <= reach.distance("drawer")[1] + 0.02
            if reach is LOW and world == "kitchen":
                assert height < PANDA_REACH.height("drawer")[0]


def test_a_parking_is_checked_with_the_arms_kinematics_where_the_bands_corner_lies_past_its_reach():
    """The door bands' far, high corner (within both bands) lies past the Panda's reach: its kinematics refuse the
    parking there and take one a few centimetres nearer; a reach without a model keeps the bands alone."""
    corner = np.array([PANDA_REACH.door_distance_m[1] - 0.02, 0.0, PANDA_REACH.door_height_m[1] - 0.005])
    normal = np.array([-1.0, 0.0, 0.0])
    assert PANDA_REACH.model == "panda_sim"
    assert not arm_grasps(PANDA_REACH, np.eye(4), corner, normal)
    assert arm_grasps(PANDA_REACH, np.eye(4), corner - [0.05, 0.0, 0.0], normal)
    assert arm_grasps(replace(PANDA_REACH, model=None), np.eye(4), corner, normal)
    T = np.eye(4)
    T[:2, 3] = [-0.05, 0.0]  # the robot parked 5 cm farther forward sees the same grip nearer
    assert arm_grasps(PANDA_REACH, T, corner, normal)
