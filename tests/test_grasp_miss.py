"""A handle seen nearer than it stands (its front's plane taken from a counter's edge before it, the calibration's
error along the approach) leaves it beyond the open fingers at the approach's end: the gripper closes on nothing, goes
on along its approach until the front stops it and closes again (deploy/control/hand.py `close_or_reach`)."""

from __future__ import annotations

from dataclasses import replace

import pytest

import deploy.control.stages as stages
from deploy.bench.open import simulate_episode
from deploy.control.state import StopReason

SEED = 0  # kitchen drawer test scenario 0: a drawer's bar handle in the open
NEARER_M = 0.025  # the handle is seen this much nearer than it stands, along its front's normal


@pytest.fixture
def seen_nearer(monkeypatch):
    perceive = stages.perceive

    def nearer(episode, *args, **kwargs):
        handle = perceive(episode, *args, **kwargs)
        return replace(handle, center=handle.center + NEARER_M * handle.normal)

    monkeypatch.setattr(stages, "perceive", nearer)


def test_a_gripper_closing_on_nothing_goes_on_and_holds_the_handle(seen_nearer):
    result = simulate_episode("drawer", SEED, split="test", target=0.1)
    assert result["success"], result["message"]


def test_closing_once_misses_it(seen_nearer, monkeypatch):
    monkeypatch.setattr(stages, "close_or_reach",
                        lambda episode, width: stages.close_and_check(episode, width, StopReason.GRASP_FAILED))
    result = simulate_episode("drawer", SEED, split="test", target=0.1)
    assert result["stop_reason"] == StopReason.GRASP_FAILED, result["message"]
