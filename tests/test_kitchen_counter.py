"""A target too low for the run and small enough for the counter (an appliance, a box with drawers) stands on the
countertop, where the robot reaches it, instead of on the floor."""

from __future__ import annotations

from partnet_objects import Front, write_object

from sim_fallback.kitchen import role_of, standing_height
from sim_fallback.kitchen_scenario import KitchenScenario, reach_problem
from sim_fallback.partnet import load_partnet
from sim_fallback.scenes import task_objects

DOOR = (Front("door", (-0.48, 0.48), (-0.55, 0.55), label="door"),)


def test_a_microwave_stands_on_the_counter_and_its_door_is_within_reach(tmp_path):
    write_object(tmp_path / "1", fronts=DOOR, category="Microwave")
    microwave = load_partnet(tmp_path / "1")
    assert microwave.size_m[2] < 0.5 and role_of(microwave) == "counter"
    assert standing_height(microwave) > 0.8 and reach_problem(microwave, "door") is None
    assert task_objects(tmp_path, "door").for_seed(0) == "1"
    for seed in range(3):
        sc = KitchenScenario.make("door", seed, "train", target=microwave)
        layout = sc.kitchen
        counter = next(s for s in layout.statics if s.name == "countertop")
        counter_top = counter.pose[2] + counter.size[2] / 2
        placed = layout.furniture[layout.target]
        assert abs(placed.pose[2] - counter_top) < 1e-6  # on the countertop, not on the floor
        objects = [s for s in layout.statics if s.name == "object" and abs(s.pose[2] - s.size[2] / 2 - counter_top)
                   < 1e-6]
        footprint = placed.footprint()
        for o in objects:  # the counter's clutter stands beside it, not inside it
            x, y = o.pose[0], o.pose[1]
            assert not (footprint[:, 0].min() < x < footprint[:, 0].max()
                        and footprint[:, 1].min() < y < footprint[:, 1].max())


def test_a_cabinet_keeps_to_the_floor(tmp_path):
    write_object(tmp_path / "2")
    cabinet = load_partnet(tmp_path / "2")
    assert role_of(cabinet) != "counter" and standing_height(cabinet) == 0.0
