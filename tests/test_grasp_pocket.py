"""Into a recessed pull's pocket under a counter's overhang (the hand goes in tilted up, its fingers filling most
of the pocket's height) the approach ends short of the bar with a finger on the pocket's lip: the tool goes on
into the pocket before closing (deploy/control/hand.py `seat_in_pocket`)."""

from __future__ import annotations

import deploy.control.stages as stages
from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason

# Kitchen test scenario 24: a top drawer's recessed pull under the counter's overhang, seen about a centimetre
# nearer than it is (the calibration's error along the approach).
POCKET_SEED = 24


def test_the_tool_goes_on_into_the_pocket_and_the_drawer_opens():
    result = simulate_episode("drawer", POCKET_SEED, split="test", target=0.1)
    assert result["success"], result["message"]


def test_easing_off_the_lip_instead_draws_the_fingers_off_the_bar(monkeypatch):
    monkeypatch.setattr(stages, "seat_in_pocket", lambda episode: False)  # the usual easing off, then closing once
    monkeypatch.setattr(stages, "close_or_reach",
                        lambda episode, width: stages.close_and_check(episode, width, StopReason.GRASP_FAILED))
    result = simulate_episode("drawer", POCKET_SEED, split="test", target=0.1)
    assert result["stop_reason"] == StopReason.GRASP_FAILED, result["message"]
