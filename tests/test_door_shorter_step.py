"""A door's step that nothing carries whole goes half as far, down to the goal's tolerance
(deploy/control/stages.py `_shorter_door_step`)."""

from __future__ import annotations

import numpy as np
import pytest

import deploy.control.stages as stages
from drivers.errors import IKError

STEP = np.radians(10.0)


def _arm_reaching(monkeypatch, reach_rad: float) -> list[float]:
    """The step's pulls are checked before moving: longer than `reach_rad`, IKError. Returns the lengths tried."""
    tried = []

    def checked_pull(episode, path, length, label, limits, step=False):
        tried.append(length)
        if length > reach_rad:
            raise IKError(f"lost the Cartesian path at s = {reach_rad:.4f} of {length:.4f}")

    monkeypatch.setattr(stages, "checked_pull", checked_pull)
    monkeypatch.setattr(stages, "_step_path", lambda episode, axis: (None, STEP, None))
    return tried


def test_a_step_out_of_reach_goes_as_far_as_half_of_it_carries(monkeypatch):
    tried = _arm_reaching(monkeypatch, np.radians(4.0))
    stages._shorter_door_step(None, None, STEP, "step 6", None, IKError("out of reach"))
    assert np.degrees(tried) == pytest.approx([5.0, 2.5])


def test_a_step_carried_by_no_length_past_the_goals_tolerance_stays_out_of_reach(monkeypatch):
    tried = _arm_reaching(monkeypatch, np.radians(0.5))
    with pytest.raises(IKError, match="the first"):
        stages._shorter_door_step(None, None, STEP, "step 6", None, IKError("the first"))
    assert min(tried) >= stages.GOAL_TOLERANCE[stages.JointType.REVOLUTE]
