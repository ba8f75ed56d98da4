"""A drawer is placed for a grasp from above only when its furniture leaves the hand room above the grip: a
drawer under a tabletop, or under another bar close above, is never offered from above (the hand would meet it)."""

from __future__ import annotations

import pytest
from partnet_objects import Front, write_object

from drivers.arm.robots import Reach
from sim_fallback.errors import PartError
from sim_fallback.furniture_body import measure_parts
from sim_fallback.kitchen_scenario import HAND_ABOVE_M, KitchenScenario
from sim_fallback.partnet import load_partnet
from sim_fallback.scenes import task_objects

ONLY_FROM_ABOVE = Reach(drawer_height_m=(3.0, 3.1), low_drawer_distance_m=(0.6, 0.7),
                        low_drawer_height_m=(0.0, 3.0))  # no grip in the usual band, every grip in the low one
TIGHT_STACK = (Front("drawer", (-0.48, 0.48), (0.45, 0.53), label="drawer"),
               Front("drawer", (-0.48, 0.48), (0.3, 0.44), label="drawer"))


def test_a_drawer_with_another_bar_close_above_is_not_grasped_from_above(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", fronts=TIGHT_STACK))
    rooms = {g.name: g.room_above_m for g in measure_parts(furniture)}
    assert rooms["bottom drawer"] < HAND_ABOVE_M <= rooms["top drawer"]
    assert task_objects(tmp_path, "drawer", reach=ONLY_FROM_ABOVE).usable == ("1",)  # the top drawer serves
    with pytest.raises(PartError) as error:
        KitchenScenario.make("drawer", 0, "test", part="bottom drawer", target=furniture, reach=ONLY_FROM_ABOVE)
    assert "grasped from above" in str(error.value) and "the hand needs" in str(error.value)
