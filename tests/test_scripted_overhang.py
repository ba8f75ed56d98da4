"""A scripted recording grasps a drawer's bar under an overhang that the usual grasp's hand would meet: it takes the
first grasp whose hand clears what stands around the furniture (here tilted up, the elbow swung out)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from partnet_objects import Front, write_object

from drivers.arm.robot_config import panda_sim_config
from sim_fallback.arm import SimArm
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.layout import StaticShape
from sim_fallback.partnet import load_partnet
from sim_fallback.scripted import grasp_handle, holds_target
from sim_fallback.world import SimWorld

HIGH_DRAWER = (Front("drawer", (-0.48, 0.48), (0.45, 0.58), label="drawer"),)  # a table's: its grip 0.76 m up
ABOVE_M, OUT_M, THICK_M = 0.09, 0.04, 0.04  # a slab's underside this far above the grip, its edge this far out


def overhung(scenario: KitchenScenario) -> KitchenScenario:
    """The scenario with a slab over its part's grip, standing out past the handle (a counter's overhang)."""
    with SimWorld(scenario) as sim:
        grip, _, normal = sim.target_handle()
    depth = 0.6
    centre = grip + normal * (OUT_M - depth / 2) + np.array([0.0, 0.0, ABOVE_M + THICK_M / 2])
    slab = StaticShape("countertop", "box", (depth, 0.8, THICK_M),
                       (*(float(v) for v in centre), float(np.arctan2(normal[1], normal[0]))), None, (0.5, 0.4, 0.3, 1))
    kitchen = scenario.kitchen
    return replace(scenario, kitchen=replace(kitchen, statics=(*kitchen.statics, slab)))


def test_a_bar_under_an_overhang_is_grasped_by_a_hand_clear_of_it(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", fronts=HIGH_DRAWER, category="Table"))
    scenario = overhung(KitchenScenario.make("drawer", 0, "test", part="drawer", target=furniture, opening=0.2))
    with SimWorld(scenario) as sim:
        arm = SimArm(sim)
        grasp_handle(sim, arm, panda_sim_config().motion_limits(arm.kin, 0.3), 0.2)
        assert holds_target(sim)
