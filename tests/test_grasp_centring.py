"""A handle that one finger alone presses when the gripper closes (it lies off the fingers' middle by more than half
its thickness: each finger closes only to the middle) is centred between them before the pull
(deploy/control/hand.py `centre_on_handle`, by the force across the fingers; `centre_by_width`, by the closed width,
for a bar); without either, the one finger drags it out of the grasp."""

from __future__ import annotations

import pytest

import deploy.control.hand as hand
from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason

# Kitchen test scenarios whose handle the closing fingers meet off their middle: a drawer's horizontal bar seen a
# centimetre low (drawer 21), a door's vertical bar in a recessed pull's pocket seen beside it (door 0).
OFF_CENTRE = [("drawer", 21, 0.1), ("door", 0, 20.0)]


def _episode(monkeypatch, task: str, seed: int, target: float, centre: bool, by_width: bool = False
             ) -> tuple[dict, list[float]]:
    """The episode with the force's centring on (`centre`) or off, the width's only when `by_width`."""
    moves: list[float] = []
    original = hand.centre_on_handle

    def recorded(episode, width: float) -> float:
        moves.append(original(episode, width) if centre else 0.0)
        return moves[-1]

    monkeypatch.setattr(hand, "centre_on_handle", recorded)
    if not by_width:
        monkeypatch.setattr(hand, "centre_by_width", lambda episode, width, open_width: 0.0)
    return simulate_episode(task, seed, split="test", target=target), moves


@pytest.mark.parametrize(("task", "seed", "target"), OFF_CENTRE)
def test_a_handle_pressed_by_one_finger_is_centred_and_the_part_opens(monkeypatch, task, seed, target):
    result, moves = _episode(monkeypatch, task, seed, target, centre=True)
    assert moves and moves[0] > 0.0  # the first close met the handle with one finger
    assert result["success"], result["message"]


def test_uncentred_the_one_finger_loses_the_handle(monkeypatch):
    """Door 0's bar, one finger on it, is pried out of the grasp by the door's turn (drawer 21's one finger, on the
    front as the faint-gap rule finds it, holds through its 10 cm)."""
    result, moves = _episode(monkeypatch, *OFF_CENTRE[1], centre=False)
    assert moves  # the scenario closes on its handle: the test above is not vacuous
    assert result["stop_reason"] == StopReason.GRASP_LOST, result["message"]


def test_a_bar_the_arm_does_not_feel_is_centred_by_the_closed_width(monkeypatch):
    result, moves = _episode(monkeypatch, *OFF_CENTRE[0], centre=False, by_width=True)
    assert moves  # the force's centring was asked and did not move
    assert result["success"], result["message"]
