"""The seed's part is one that can open as far as the task asks: a drawer whose slides end short of the target is
never a "drawer 45 cm" episode (it could only fail), and an object with no such part gets one line saying so."""

from __future__ import annotations

import pytest
from partnet_objects import write_object

from drivers.arm.robots import Reach
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.partnet import PartNetError, load_partnet
from sim_fallback.scenes import task_objects


def _travel(scenario: KitchenScenario) -> float:
    return scenario.kitchen.target_furniture.furniture.part(scenario.part).upper


def test_the_seeds_drawer_travels_as_far_as_asked():
    asked = 0.45
    short = [s for s in (0, 5) if _travel(KitchenScenario.make("drawer", s, "test")) < asked]
    assert short, "these test seeds draw a free-standing chest whose drawers stop short of 45 cm"
    for seed in short:
        assert _travel(KitchenScenario.make("drawer", seed, "test", opening=asked)) >= asked


def test_an_object_whose_drawers_stop_short_is_named_with_why(tmp_path):
    write_object(tmp_path / "1")
    travel = next(p.upper for p in load_partnet(tmp_path / "1").parts if p.kind == "drawer")
    low_reach = Reach(drawer_height_m=(0.3, 0.9))  # an arm that reaches this small object's drawer
    assert task_objects(tmp_path, "drawer", reach=low_reach, opening=travel - 0.01).usable == ("1",)
    with pytest.raises(PartNetError) as error:
        task_objects(tmp_path, "drawer", reach=low_reach, opening=travel + 0.05)
    line = str(error.value)
    assert "open at most" in line and f"{travel:.2f} m" in line and "ask for less" in line
