"""A scripted recording films a low part from a tripod lowered to it (its head 0.2-0.6 m above the part's front
centre), not from the usual 1.2-1.8 m above the floor; a part at a height the usual tripod suits keeps the
scenario's camera."""

from __future__ import annotations

from partnet_objects import Front, write_object

from drivers.arm.robots import Reach
from sim_fallback.furniture_body import measure_parts
from sim_fallback.kitchen_scenario import RECORD_ABOVE_M, TRIPOD_LOW_M, KitchenScenario, recording_camera
from sim_fallback.partnet import load_partnet

TWO_DOORS = (Front("door", (-0.48, 0.48), (0.05, 0.58), label="door"),
             Front("door", (-0.48, 0.48), (-0.58, -0.05), label="door"))
REACH = Reach(door_height_m=(0.45, 0.5), low_door_distance_m=(0.6, 0.75), low_door_height_m=(0.1, 0.16))


def centre_above_floor(scenario: KitchenScenario) -> float:
    placed = scenario.kitchen.target_furniture
    [part] = [g for g in measure_parts(placed.furniture) if g.name == scenario.part]
    return float((placed.T @ [*part.front_centre, 1.0])[2]) + scenario.base_height_m


def test_a_low_door_is_filmed_from_a_tripod_lowered_to_it(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", fronts=TWO_DOORS))
    for seed in range(3):
        scenario = KitchenScenario.make("door", seed, "train", part="bottom door", target=furniture, reach=REACH)
        centre = centre_above_floor(scenario)
        assert centre + RECORD_ABOVE_M[1] < 1.2  # too low for the usual tripod
        camera = recording_camera(scenario)
        eye_up = camera.eye[2] + scenario.base_height_m
        assert camera.kind == "base" or max(centre + RECORD_ABOVE_M[0], TRIPOD_LOW_M) - 1e-9 <= eye_up <= \
            max(centre + RECORD_ABOVE_M[1], TRIPOD_LOW_M) + 1e-9
        assert camera != scenario.camera and scenario.camera.eye[2] + scenario.base_height_m >= 0.95


def test_a_part_at_a_comfortable_height_keeps_the_scenarios_camera(tmp_path):
    door = (Front("door", (-0.48, 0.48), (-0.55, 0.55), label="door"),)
    microwave = load_partnet(write_object(tmp_path / "1", fronts=door, category="Microwave"))  # on the countertop
    for seed in range(3):
        scenario = KitchenScenario.make("door", seed, "train", target=microwave)
        assert centre_above_floor(scenario) + RECORD_ABOVE_M[1] >= 1.2
        assert recording_camera(scenario) == scenario.camera
