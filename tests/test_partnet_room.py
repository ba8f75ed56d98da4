"""A kitchen leaves a PartNet-Mobility object the room its parts need: a door hinged inside its edge swings that
edge past the body's side, and a unit standing flush beside it would hold the door shut."""

from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from partnet_objects import BODY, PANEL, Front, write_object

from drivers.arm.robots import Reach
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.partnet import load_partnet
from sim_fallback.world import SimWorld

FULL_DOOR = (Front("door", (-BODY[1] / 2, BODY[1] / 2), (-0.58, 0.58), label="door", hinge_depth=PANEL),)

LOW_REACH = Reach(door_height_m=(0.2, 0.78))  # an arm that reaches this low cabinet's grip (the scene is tested)


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


def deepest_touch_m(world: SimWorld, angle: float) -> float:
    """The deepest the target door, at `angle`, reaches into the units around it (m; 0 when it touches none)."""
    c, target = world.client, world.target
    pb.resetJointState(target.body, target.joint, angle, physicsClientId=c)
    pb.performCollisionDetection(physicsClientId=c)
    units = set(world.furniture_ids) - {target.body}
    depths = [-cp[8] for cp in pb.getContactPoints(bodyA=target.body, physicsClientId=c)
              if cp[2] in units and cp[3] == target.joint]
    return max(depths, default=0.0)


def test_a_door_swinging_its_edge_past_the_side_meets_no_neighbour(tmp_path):
    cabinet = load_partnet(write_object(tmp_path / "1", fronts=FULL_DOOR))
    beside = 0
    for seed in range(4):
        scenario = KitchenScenario.make("door", seed, "train", target=cabinet, reach=LOW_REACH)
        placed = scenario.kitchen.furniture[scenario.kitchen.target]
        beside += any(np.min(np.linalg.norm(p.footprint()[:, None] - placed.footprint()[None], axis=2)) < 1e-3
                      for p in scenario.kitchen.furniture if p is not placed)
        with SimWorld(scenario) as world:
            for angle in np.radians([0.0, 30.0, 60.0, 90.0]):
                assert deepest_touch_m(world, angle) < 2e-3, (seed, np.degrees(angle))  # a touch, not a jam
    assert beside >= 2  # units stood against it in most kitchens
    sweep = PANEL * cabinet.scale  # hinged at its back face, the door's front edge swings out its thickness
    assert cabinet.size_m[0] >= BODY[1] * cabinet.scale + 2 * sweep
