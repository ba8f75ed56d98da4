"""A part a user names is placed in the reach its own grip calls for: a low door under one at a comfortable height is
grasped from above, not refused as out of reach because its furniture has a part in the usual bands."""

from __future__ import annotations

from partnet_objects import Front, write_object

from drivers.arm.robots import Reach
from sim_fallback.kitchen_scenario import KitchenScenario, named_reach
from sim_fallback.partnet import load_partnet

TWO_DOORS = (Front("door", (-0.48, 0.48), (0.05, 0.58), label="door"),
             Front("door", (-0.48, 0.48), (-0.58, -0.05), label="door"))  # grips 0.49 and 0.15 m above the floor
REACH = Reach(door_height_m=(0.45, 0.5), low_door_distance_m=(0.6, 0.75), low_door_height_m=(0.1, 0.16))


def test_a_named_low_door_is_placed_for_a_grasp_from_above(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", fronts=TWO_DOORS))
    low = KitchenScenario.make("door", 0, "test", part="bottom door", target=furniture, reach=REACH)
    assert low.part == "bottom door"
    assert low.base_height_m <= 0.06  # its grip 0.1-0.16 m above the robot's base: the band from above
    top = KitchenScenario.make("door", 0, "test", part="top door", target=furniture, reach=REACH)
    assert top.part == "top door"


def test_the_named_reach_is_the_usual_one_for_a_grip_at_a_comfortable_height(tmp_path):
    from sim_fallback.furniture_body import measure_parts
    from sim_fallback.kitchen import standing_height
    from sim_fallback.layout import Placed

    furniture = load_partnet(write_object(tmp_path / "1", fronts=TWO_DOORS))
    placed = Placed(furniture, (0.0, 0.0, standing_height(furniture), 0.0))
    parts = {g.name: g for g in measure_parts(furniture)}
    assert named_reach(placed, parts["top door"], "door", REACH) == REACH
    assert named_reach(placed, parts["bottom door"], "door", REACH) == REACH.from_above("door")
