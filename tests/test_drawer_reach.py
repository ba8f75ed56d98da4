"""A drawer's pull that runs out of the arm's reach: the arm takes the handle again from another configuration and
goes on, or says in one line how near its base the handle came.

The world's truth is read by the tests only, after the episode (the score)."""

from __future__ import annotations

from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason


def test_a_pull_that_loses_the_arms_path_goes_on_from_another_arm_configuration():
    """Test kitchen drawer 69 pulled 45 cm: the first pull loses the Cartesian path at its end; held again from
    another configuration, the arm carries the drawer to the target."""
    result = simulate_episode("drawer", 69, "test", target=0.45)
    assert result["stop_reason"] == StopReason.TARGET_REACHED and result["success"], result["message"]


def test_a_pull_no_arm_configuration_carries_says_how_near_the_arms_base_the_handle_came():
    """Test kitchen drawer 51 pulled 45 cm brings its handle within 12 cm of the arm's base axis: the pull past the
    target runs out of reach and no configuration carries the rest from there."""
    result = simulate_episode("drawer", 51, "test", target=0.45)
    assert result["stop_reason"] == StopReason.IK_INFEASIBLE, result["message"]
    assert "from the arm's base axis" in result["message"] and "\n" not in result["message"]
    assert result["true_opened_m"] > 0.4
