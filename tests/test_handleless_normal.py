"""A part whose model gives no handle faces the way it opens: its front normal is the level direction its centre
moves as its joint opens, whichever model axis the object's front is on (the robot is parked and the camera placed
in front of it by that normal)."""

from __future__ import annotations

import numpy as np
import pytest
from partnet_objects import Front, write_object

from sim_fallback.furniture_body import measure_parts
from sim_fallback.partnet import load_partnet

BARE = (Front("drawer", (-0.48, 0.48), (0.25, 0.58), handle=None, label="drawer"),
        Front("door", (-0.48, 0.48), (-0.58, 0.23), handle=None, label="rotation_door"))


@pytest.mark.parametrize("front_axis", ["+z", "-x"])
def test_a_part_without_a_handle_faces_out_of_the_furniture_front(tmp_path, front_axis):
    furniture = load_partnet(write_object(tmp_path / "1", front_axis=front_axis, fronts=BARE))
    normals = {g.name: g.normal for g in measure_parts(furniture)}
    assert np.allclose(normals["drawer"], [1.0, 0.0, 0.0], atol=1e-6)
    assert normals["door"] @ [1.0, 0.0, 0.0] > np.cos(np.radians(3.0)) and abs(normals["door"][2]) < 1e-9


def test_a_part_without_a_handle_is_gripped_in_the_middle_of_its_front(tmp_path):
    furniture = load_partnet(write_object(tmp_path / "1", front_axis="+z", fronts=BARE))
    drawer = next(g for g in measure_parts(furniture) if g.name == "drawer")
    assert np.allclose(drawer.grip, drawer.front_centre, atol=1e-6)
