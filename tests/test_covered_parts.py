"""A part standing behind another part's front (a cabinet's drawers inside it, behind its closed door) cannot be
opened by a pull from outside: it is never the seed's part, and an object with only such parts of the task's kind
gets one line saying so, while its other parts still serve."""

from __future__ import annotations

import numpy as np
import pytest
from partnet_objects import Front, write_object

from drivers.arm.robots import Reach
from sim_fallback.covered import covering_part
from sim_fallback.furniture_body import PartGeometry
from sim_fallback.partnet import PartNetError
from sim_fallback.scenes import task_objects

LOW_REACH = Reach(drawer_height_m=(0.3, 0.9), door_height_m=(0.3, 0.9))  # reaches the small objects' grips


def _part(name: str, lo, hi) -> PartGeometry:
    lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
    return PartGeometry(name, "drawer", (lo, hi), (lo + hi) / 2, np.array([1.0, 0.0, 0.0]))


def test_a_drawer_inside_behind_a_door_is_covered_and_neighbours_in_one_plane_are_not():
    door = _part("door", (0.22, -0.19, 0.18), (0.29, 0.19, 0.68))
    inside = _part("inner drawer", (-0.24, -0.15, 0.43), (0.23, 0.15, 0.48))
    top = _part("top drawer", (-0.2, -0.23, 0.28), (0.26, 0.23, 0.43))
    bottom = _part("bottom drawer", (-0.2, -0.23, 0.0), (0.3, 0.23, 0.29))  # its handle stands 4 cm out
    assert covering_part(inside, [door, inside]) == "door"
    assert covering_part(door, [door, inside]) is None
    assert covering_part(top, [top, bottom]) is None and covering_part(bottom, [top, bottom]) is None


def test_an_object_whose_drawers_stand_behind_its_door_is_named_with_why(tmp_path):
    fronts = (Front("door", (-0.48, 0.48), (-0.58, 0.58), label="rotation_door"),
              Front("drawer", (-0.4, 0.4), (0.1, 0.4), handle=None, label="drawer", inset=0.1))
    write_object(tmp_path / "1", fronts=fronts)
    with pytest.raises(PartNetError) as error:
        task_objects(tmp_path, "drawer", reach=LOW_REACH)
    line = str(error.value)
    assert "cannot be used" in line and "drawer behind its door" in line
    assert task_objects(tmp_path, "door", reach=LOW_REACH).usable == ("1",)
