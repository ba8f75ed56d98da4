"""A door's pre-grasp is planned for the whole arc to its goal first (deploy/control/stages.py)."""

from __future__ import annotations

from deploy.control.stages import PLANNED_DOOR_ARCS_DEG, planned_door_arcs_deg


def test_a_wide_opening_is_planned_whole_before_the_usual_arcs():
    assert planned_door_arcs_deg(75.0) == (75.0, *PLANNED_DOOR_ARCS_DEG)


def test_a_small_opening_keeps_the_usual_arcs():
    assert planned_door_arcs_deg(25.0) == PLANNED_DOOR_ARCS_DEG
