"""Gap lines between fronts against lines inside a front, on synthetic D415 frames: the end of a recessed pull's
slot (a short dark line across a thin drawer's middle) does not end the drawer's front; a gap running along the
drawer's whole side does."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.front import find_front
from deploy.perception.front_extent import gap_lines
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
DEPTH_M = 2.0  # straight ahead: a pixel is 3.3 mm on the front
DRAWER_V, DRAWER_U = (200, 248), (110, 320)  # 0.16 x 0.70 m
SLOT_V = (215, 233)  # the slot's end: 6 cm of the drawer's 16 cm height, 5 cm from either edge


def _frame(line_v: tuple[int, int]) -> Frame:
    """A thin drawer 2 m ahead before a pale wall 2.4 m away, with a one-pixel dark line at column 250 over rows
    `line_v`."""
    depth = np.full((480, 640), 2.4, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    drawer = (slice(*DRAWER_V), slice(*DRAWER_U))
    depth[drawer], color[drawer] = DEPTH_M, (150, 100, 60)
    color[line_v[0]:line_v[1], 250] = (90, 60, 36)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


def test_a_line_across_the_middle_of_a_drawer_is_no_gap_but_one_along_its_side_is():
    surface = np.ones((30, 40), bool)  # 30 lines, each four 3 cm stretches long
    grey = np.full((30, 40), 0.6)
    grey[10, 9:27] = 0.4  # along the two middle stretches
    grey[20, :] = 0.4
    assert np.flatnonzero(gap_lines(grey, surface, 0.0033)).tolist() == [20]


@pytest.mark.parametrize("line_v, width_m", [(SLOT_V, 0.70), (DRAWER_V, 140 * DEPTH_M / K.fx)])
def test_a_recessed_pulls_slot_end_does_not_end_the_front(line_v, width_m):
    front = find_front(_frame(line_v), np.zeros((480, 640), bool), 160, 224)
    assert front.width_m == pytest.approx(width_m, abs=0.03)
