"""A drawer pulled less than the pull the arm's drawer bands are set for is grasped the usual way lower down, where the
arm's kinematics carry the shorter pull: a drawer just under the usual band is placed for a short pull only."""

from __future__ import annotations

from dataclasses import replace

from partnet_objects import Front, write_object

from drivers.arm.robots import PANDA_REACH
from sim_fallback.kitchen_scenario import KitchenScenario, reach_problem, short_pull_reach
from sim_fallback.partnet import load_partnet
from sim_fallback.world import SimWorld

HIGH_DRAWER = (Front("drawer", (-0.48, 0.48), (0.3, 0.58), label="drawer"),)  # a table's: its grip 0.71 m up
FRONT_ONLY = replace(PANDA_REACH, low_drawer_distance_m=None, low_drawer_height_m=None)  # the Panda, never from above


def test_a_drawer_under_the_usual_band_is_placed_for_a_short_pull_only(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", fronts=HIGH_DRAWER, category="Table"))
    assert reach_problem(furniture, "drawer", FRONT_ONLY, 0.45) is not None
    assert reach_problem(furniture, "drawer", FRONT_ONLY, 0.2) is None
    short = short_pull_reach(FRONT_ONLY, "drawer", 0.2)
    assert short.drawer_height_m[0] < PANDA_REACH.drawer_height_m[0] and short.drawer_distance_m == \
        PANDA_REACH.drawer_distance_m
    scenario = KitchenScenario.make("drawer", 0, "test", part="drawer", target=furniture, opening=0.2,
                                    reach=FRONT_ONLY)
    with SimWorld(scenario) as sim:
        height = float(sim.target_handle()[0][2])
    assert short.drawer_height_m[0] - 1e-6 <= height < PANDA_REACH.drawer_height_m[0]


def test_a_pull_as_long_as_the_bands_or_a_door_keeps_the_usual_bands():
    assert short_pull_reach(PANDA_REACH, "drawer", PANDA_REACH.drawer_pull_m) is None
    assert short_pull_reach(PANDA_REACH, "door", 0.2) is None
    assert short_pull_reach(PANDA_REACH.usual(), "drawer", 0.2) is None
