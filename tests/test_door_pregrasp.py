"""A door's pre-grasp configuration is planned for the arc about its likely hinge (deploy/control/stages.py)."""

from __future__ import annotations

import deploy.control.stages as stages
from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason

# Test door 44 stands far to one side: a configuration chosen for a straight pull turns the wrist (joint 5) onto
# its speed limit 7 deg into the arc.
FAR_DOOR_SEED = 44


def test_a_door_pregrasp_planned_for_the_arc_carries_the_wrist_through_it():
    result = simulate_episode("door", FAR_DOOR_SEED, split="test", target=20.0)
    assert result["success"], result["message"]


def test_planned_for_a_straight_pull_the_wrist_runs_out_of_speed_on_the_arc(monkeypatch):
    monkeypatch.setattr(stages, "PLANNED_DOOR_ARCS_DEG", ())
    result = simulate_episode("door", FAR_DOOR_SEED, split="test", target=20.0)
    # the scenario does need the arc: the test above is not vacuous
    assert result["stop_reason"] == StopReason.IK_INFEASIBLE
    assert "panda_joint5" in result["message"]
