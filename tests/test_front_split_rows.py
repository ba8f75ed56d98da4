"""A rectangle cut narrower than it grew (fronts side by side wider than 1 m together, their gap too faint to end
it) has its top and bottom judged again over its own columns: a neighbour's gap across the columns it lost does not
bound the pointed front."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.front import find_front
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
DEPTH_M = 2.0  # straight ahead: a pixel is 3.3 mm on the front
BLOCK_V, BLOCK_U = (150, 252), (100, 460)  # 0.34 x 1.20 m: front A (left half) beside unit B (right half)
SPLIT_U = 280  # A's right side, B's left
B_GAP_V = 184  # the gap between B's upper and lower fronts, a third of the way down
SHOWN_V = (223, 252)  # the part of A's side gap that shows (the rest lies in a shadow, as dark as the slit)


def _frame() -> Frame:
    """A 1.2 m wide block of fronts 2 m ahead before a pale wall 2.4 m away: B's gap drawn across B's width, A's side
    gap drawn along its lowest 30 % only."""
    depth = np.full((480, 640), 2.4, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    block = (slice(*BLOCK_V), slice(*BLOCK_U))
    depth[block], color[block] = DEPTH_M, (150, 100, 60)
    color[B_GAP_V, SPLIT_U + 1:BLOCK_U[1]] = (90, 60, 36)
    color[SHOWN_V[0]:SHOWN_V[1], SPLIT_U] = (90, 60, 36)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


def test_a_neighbours_gap_does_not_cut_the_front_after_a_wide_rectangle_is_split():
    front = find_front(_frame(), np.zeros((480, 640), bool), 190, 235)
    pixel_m = DEPTH_M / K.fx
    assert front.width_m == pytest.approx((SPLIT_U - BLOCK_U[0]) * pixel_m, abs=0.03)
    assert front.height_m == pytest.approx((BLOCK_V[1] - BLOCK_V[0]) * pixel_m, abs=0.03)  # not 0.21 m: cut at B's gap
