"""A drawer episode ends in success only when the drawer the user pointed at has left its place: the gripper carrying
another part (a neighbour's handle taken for the pointed front's) is said in one line, not claimed as an opening.

The world's truth is read by the tests only, after the episode (the score)."""

from __future__ import annotations

import numpy as np
from test_pointed_episode import THREE_DRAWERS
from test_pointer import kitchen_scene

from deploy.bench.open import simulate_episode
from deploy.control import observer
from deploy.control.observer import still_around
from deploy.control.session import OpenRequest, open_object
from deploy.control.state import StopReason
from deploy.perception.base import Pointer
from deploy.perception.pointing import point_at
from drivers.camera.base import Frame, Intrinsics


def _frame(depth: np.ndarray) -> Frame:
    h, w = depth.shape
    return Frame(index=0, t=0.0, color=np.zeros((h, w, 3), np.uint8), depth_m=depth.astype(np.float32),
                 intrinsics=Intrinsics(w, h, 600.0, 600.0, w / 2, h / 2))


def test_a_surface_still_there_is_told_from_one_that_moved_or_is_hidden():
    first = _frame(np.full((60, 80), 1.0))
    noisy = _frame(1.0 + np.random.default_rng(0).normal(0.0, 0.003, (60, 80)))
    assert still_around(first, noisy, (30, 40)) is True
    nearer = first.depth_m.copy()
    nearer[20:40, 30:50] = 0.9  # a front 10 cm out toward the camera
    assert still_around(first, _frame(nearer), (30, 40)) is False
    hidden = first.depth_m.copy()
    hidden[:, 35:80] = 0.0  # the arm's pixels, removed by the self-filter
    assert still_around(first, _frame(hidden), (30, 40)) is None
    assert still_around(first, noisy, (70, 40)) is None  # off the image


def test_a_front_pulled_out_is_told_moved_though_one_place_on_it_reads_its_old_depth():
    first = _frame(np.full((60, 80), 1.0))
    out = first.depth_m.copy()
    out[10:50, 20:60] = 0.88  # the front 12 cm out ...
    out[25:36, 35:46] = 1.0  # ... and at the pointed pixel the drawer's inside, at the front's old depth
    front = np.zeros((60, 80), bool)
    front[10:50, 20:60] = True
    assert still_around(first, _frame(out), (30, 40)) is True
    assert observer.still_on(first, _frame(out), front) is False
    assert observer.still_on(first, first, front) is True


def test_a_neighbours_drawer_carried_out_is_not_claimed_as_the_pointed_ones(monkeypatch):
    """Test kitchen seed THREE_DRAWERS, a stack of three drawers: the user points at the top one, and the pointer
    finds the middle one's front and handle (as a pointer that took the neighbour's front for the pointed one
    would). The arm carries the middle drawer out; the episode stops saying the pointed one did not follow."""
    scene = kitchen_scene("drawer", THREE_DRAWERS, part="middle drawer")
    pointed, neighbour = scene.pixel("top drawer"), scene.pixel("middle drawer")

    def neighbours(frame, robot, pointer, gripper=None):
        return point_at(frame, robot, Pointer(*neighbour), gripper=gripper)

    monkeypatch.setattr(observer, "point_at", neighbours)
    request = OpenRequest(task="drawer", seed=THREE_DRAWERS, split="test", part="middle drawer", point=pointed,
                          distance_m=0.15)
    result = open_object(request, keep_run_dir=False)
    assert result["stop_reason"] == StopReason.NOT_FOLLOWED, result["message"]
    assert not result["success"] and result["true_opened_m"] > 0.1  # the middle drawer came out
    assert "did not follow" in result["message"] and "\n" not in result["message"]


def test_the_pointed_drawer_carried_out_is_not_stopped():
    result = simulate_episode("drawer", THREE_DRAWERS, "test", target=0.15, part="middle drawer")
    assert result["stop_reason"] == StopReason.TARGET_REACHED and result["success"], result["message"]


def test_a_drawer_seen_leaving_its_place_is_not_doubted_when_its_inside_stands_where_its_front_was():
    """Test kitchen drawer 81: carried 29 cm out, the drawer shows its inside at the pointed pixel, about as deep as
    its front stood; the front seen gone at 10 cm settled that it follows."""
    result = simulate_episode("drawer", 81, "test", target=0.30)
    assert result["stop_reason"] == StopReason.TARGET_REACHED and result["success"], result["message"]
