"""A tall unit shallower than the base run is packed out from the wall, its front level with the run's (a fitted
kitchen's fronts line up, so the run's fronts and counter do not stand out beside its door's edge); a parking from
which no camera sees the part is parked again in the same kitchen, not given up for another."""

from __future__ import annotations

import numpy as np

import sim_fallback.kitchen_scenario as kitchen_scenario
from sim_fallback.errors import SceneError
from sim_fallback.kitchen import random_room
from sim_fallback.unit_families import Carcass, random_carcass, random_look, random_unit


def _shallow_tall(rng: np.random.Generator, depth: float = 0.42):
    look = random_look("test", rng)
    deep = random_carcass("test", "tall", rng)
    shallow = Carcass(depth, deep.height_m, deep.plinth_m, deep.wall_m, deep.front_m)
    return look, random_unit("tall", "doors", 0.6, shallow, look, "test", rng, "test tall unit").furniture()


def test_a_tall_unit_shallower_than_the_run_stands_with_its_front_level_with_the_runs():
    for seed in range(4):
        rng = np.random.default_rng(seed)
        look, tall = _shallow_tall(rng)
        room = random_room(tall, "tall", "test", look, rng, "test")
        target = room.furniture[room.target]
        fronts = [p.footprint()[:, 0].max() for k, p in enumerate(room.furniture)
                  if k != room.target and p.pose[2] == 0.0 and p.furniture.size_m[2] < 1.2]  # the base run
        assert np.isclose(target.footprint()[:, 0].max(), max(fronts))
        assert target.footprint()[:, 0].min() > 0.1  # off the wall


def test_a_parking_no_camera_sees_the_part_from_is_parked_again_in_the_same_kitchen(monkeypatch):
    rooms, cameras = [], []
    real_room, real_camera = kitchen_scenario.random_room, kitchen_scenario._camera

    def room(*args, **kwargs):
        rooms.append(1)
        return real_room(*args, **kwargs)

    def camera(*args, **kwargs):
        cameras.append(1)
        if len(cameras) == 1:
            raise SceneError("no camera sees it from here")
        return real_camera(*args, **kwargs)

    monkeypatch.setattr(kitchen_scenario, "random_room", room)
    monkeypatch.setattr(kitchen_scenario, "_camera", camera)
    _, tall = _shallow_tall(np.random.default_rng(0), 0.6)
    kitchen_scenario.KitchenScenario.make("door", 0, "test", target=tall, opening=float(np.radians(45)))
    assert len(rooms) == 1 and len(cameras) == 2
