"""A handle that one finger alone stops on, closing, while the arm feels nothing across the fingers (a finger that
barely presses), is centred between them by the closed width (deploy/control/hand.py `centre_by_width`): the tool
ends where both fingers hold it, on grippers whose fingers close independently or together."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import deploy.control.hand as hand
from deploy.control.state import StopReason

OPEN_M = 0.08
THICKNESS_M = 0.009  # a thin bar across the fingers


class FakeGripper:
    """Fingers closing along the tool's y axis (world z here) on a bar `offset_m` above the tool: independent fingers
    stop one on the bar and the other at the middle, fingers moving together both at the first touch."""

    control_period_s = 0.01

    def __init__(self, episode, together: bool) -> None:
        self.episode, self.together, self.width = episode, together, OPEN_M

    def set_gripper(self, width_m: float, force_n: float | None = None) -> None:
        if width_m > 0.0:
            self.width = width_m
            return
        off = abs(self.episode.bar_z - self.episode.p[2])
        self.width = 2 * off + THICKNESS_M if self.together else max(off + THICKNESS_M / 2, THICKNESS_M)

    def state(self) -> SimpleNamespace:
        return SimpleNamespace(gripper_width_m=self.width)

    def sync(self) -> None:
        pass


class FakeEpisode:
    """The hand's view of an episode: a tool pointing along x with its fingers closing along z, nothing felt."""

    grip_force_n = 40.0

    def __init__(self, offset_m: float, measured_thickness_m: float, together: bool = False,
                 opened: float = 0.0) -> None:
        self.p, self.bar_z = np.zeros(3), offset_m
        self.arm = FakeGripper(self, together)
        self.state = SimpleNamespace(handle=SimpleNamespace(thickness_m=measured_thickness_m), opened=opened)

    def tool(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
        T[:3, 3] = self.p
        return T

    def wait(self, duration_s: float) -> None:
        pass


@pytest.fixture(autouse=True)
def _unfelt(monkeypatch):
    """The arm feels nothing across the fingers; a step moves the tool exactly."""
    monkeypatch.setattr(hand, "_force_at_rest", lambda episode: (np.zeros(3), episode.tool()))

    def step(episode, T, direction, length):
        episode.p = T[:3, 3] + np.asarray(direction) * length

    monkeypatch.setattr(hand, "_step", step)


@pytest.mark.parametrize(("offset", "together"), [(0.012, False), (-0.017, False), (0.010, True), (-0.008, True)])
def test_a_bar_one_finger_stops_on_ends_between_both_fingers(offset, together):
    episode = FakeEpisode(offset, measured_thickness_m=0.014, together=together)
    hand.close_and_check(episode, OPEN_M, StopReason.GRASP_FAILED)
    assert abs(episode.bar_z - episode.p[2]) <= THICKNESS_M / 2
    assert episode.arm.width == pytest.approx(THICKNESS_M + 2 * abs(episode.bar_z - episode.p[2]) * together)


def test_a_held_bar_measured_thinner_stays_where_it_was_held():
    episode = FakeEpisode(0.001, measured_thickness_m=0.006)
    hand.close_and_check(episode, OPEN_M, StopReason.GRASP_FAILED)
    assert episode.p == pytest.approx(np.zeros(3))
    assert episode.arm.width == pytest.approx(THICKNESS_M)


def test_a_bar_as_thick_as_the_closed_width_is_not_probed():
    episode = FakeEpisode(0.012, measured_thickness_m=0.03)
    hand.close_and_check(episode, OPEN_M, StopReason.GRASP_FAILED)
    assert episode.p == pytest.approx(np.zeros(3))


def test_an_opened_part_is_not_probed_by_width():
    """Re-grasping a door opened 0.3 rad: the fingers, closed wider than the handle, stay where they closed (each
    probe would open them, and the door, let go, swings back on its spring between the probes)."""
    episode = FakeEpisode(0.008, measured_thickness_m=0.006, opened=0.3)
    hand.close_and_check(episode, OPEN_M, StopReason.GRASP_LOST)
    assert episode.p == pytest.approx(np.zeros(3))
    assert episode.arm.width == pytest.approx(0.008 + THICKNESS_M / 2)  # one finger on it, as it closed
