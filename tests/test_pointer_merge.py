"""The pointed front not merged with its neighbours, on synthetic D415 frames: two fronts side by side, coplanar,
whose gap shows too faintly along their height to end the front's rectangle, are parted at it when together they are
wider than a front is; a wide front with no gap line stays whole."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.front import find_front
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
DEPTH_M = 2.0  # the fronts' distance, straight ahead: a pixel is 3.3 mm on them
FRONTS_V = (135, 345)  # 0.7 m tall


def _frame(fronts_u: tuple[int, int], gap_u: int | None) -> Frame:
    """Fronts of one colour 2 m ahead over columns `fronts_u` before a pale wall 2.4 m away; a one-pixel gap line
    slightly darker than them at column `gap_u`, shown along 30 % of its length (in 6 cm dashes: the rest of the slit
    is narrower than a pixel)."""
    depth = np.full((480, 640), 2.4, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    fronts = (slice(*FRONTS_V), slice(*fronts_u))
    depth[fronts], color[fronts] = DEPTH_M, (150, 100, 60)
    if gap_u is not None:
        dash = int(round(0.06 / (DEPTH_M / K.fx)))
        for v in range(FRONTS_V[0], FRONTS_V[1], int(dash / 0.3)):
            color[v:min(v + dash, FRONTS_V[1]), gap_u] = (120, 80, 48)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


def _front(fronts_u: tuple[int, int], gap_u: int | None, u: int):
    return find_front(_frame(fronts_u, gap_u), np.zeros((480, 640), bool), u, 240)


@pytest.mark.parametrize("u, side", [(200, "right"), (440, "left")])
def test_two_fronts_side_by_side_wider_than_a_front_are_parted_at_their_faint_gap(u, side):
    front = _front((110, 530), 320, u)  # 0.7 + 0.7 m
    assert front.width_m == pytest.approx(0.7, abs=0.03)
    assert front.ended[side] == "gap"


def test_a_wide_front_without_a_gap_line_stays_whole():
    front = _front((130, 510), None, 200)  # 1.27 m
    assert front.width_m == pytest.approx(380 * DEPTH_M / K.fx, abs=0.03)

