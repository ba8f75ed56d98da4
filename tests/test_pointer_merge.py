"""The pointed front not merged with its neighbours, on synthetic D415 frames: two fronts side by side, coplanar,
whose gap shows too faintly along their height to end the front's rectangle, are parted at it when together they are
wider than a front is; a wide front with no gap line stays whole; stacked drawers whose bars stand over their top
edges are cut at the lower bar."""

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


def _stack_frame(bars_at: int) -> Frame:
    """Two drawers 1 m ahead, one above the other (rows 100-250 and 250-400, 0.25 m tall each), their gap not seen,
    each with a bar standing out 3 cm, `bars_at` pixels under its top (negative: over it), before a wall 1.3 m
    away."""
    depth = np.full((480, 640), 1.3, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    depth[100:400, 170:470], color[100:400, 170:470] = 1.0, (150, 100, 60)
    for top in (100, 250):
        bar = (slice(top + bars_at, top + bars_at + 6), slice(245, 395))
        depth[bar], color[bar] = 0.97, (128, 128, 128)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    return Frame(0, 0.0, color, depth, K, T)


def test_stacked_drawers_with_bars_on_their_top_edges_are_cut_at_the_lower_bar():
    """Bars standing over the drawers' top edges (1 cm above), the gap between the drawers not seen, the pixel in
    the upper drawer nearer the lower bar: the gap lies at the lower bar, as the upper bar lies at the upper drawer's
    top, so the pixel is the upper drawer's."""
    frame = _stack_frame(bars_at=-6)
    front = find_front(frame, np.zeros((480, 640), bool), 320, 200)
    assert front.mask[200, 320] and not front.mask[300, 320]
    assert 0.18 < front.height_m < 0.27
