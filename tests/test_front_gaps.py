"""Gap lines between fronts against lines inside a front, on synthetic D415 frames: the end of a recessed pull's
slot (a short dark line across a thin drawer's middle) does not end the drawer's front; a gap running along the
drawer's whole side does; a bar across a drawer, seen in colour as lines, does not."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.front import find_front
from deploy.perception.front_extent import _faint_gaps, gap_lines, slit_lines
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


def _profile(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(grey, judged, offset) of 120 lines 90 cells long (3.3 mm cells) across a flat front lit evenly, the D415's
    noise (1 mm, correlated over 3 cells) on its depth."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 0.001, (40, 30))
    offset = np.kron(noise, np.ones((3, 3)))
    grey = np.full(offset.shape, 0.4)
    return grey, np.ones(offset.shape, bool), offset


@pytest.mark.parametrize("seed", range(5))
def test_a_gap_lit_like_its_fronts_is_a_gap_where_the_depth_sees_its_slit(seed):
    grey, judged, offset = _profile(seed)
    grey[60] += 0.004  # one 8-bit level lighter: too faint for GAP_CONTRAST
    assert not gap_lines(grey, judged, 0.0033)[60]
    assert not _faint_gaps(grey, judged, offset, judged, 0.0033).any()  # no slit in depth: a texture's line
    offset[60] -= 0.006  # the D415 sees a few millimetres into the slit
    assert np.flatnonzero(_faint_gaps(grey, judged, offset, judged, 0.0033)).tolist() == [60]


def test_a_faint_line_over_a_dip_is_no_gap_on_a_grained_front():
    grey, judged, offset = _profile(0)
    rng = np.random.default_rng(1)
    grey += np.kron(rng.normal(0.0, 0.01, (120, 1)), np.ones((1, 90)))  # grain: lines along the whole profile
    offset[60] -= 0.006
    assert not _faint_gaps(grey, judged, offset, judged, 0.0033).any()


def test_a_bar_across_a_drawer_too_thin_for_the_smoothed_depth_does_not_end_its_front():
    """A 10 mm bar 3 cm proud across nearly the whole width of a 0.40 m drawer: the smoothed depth averages it into
    the plane and its bright outline is a thin line along the band, but its measured depth stands out of the front
    there: no surface a gap is judged on, so the front goes on past it up to the drawer's top (before: it ended
    under the bar, and the bar outside it was refused as the drawer's handle)."""
    depth = np.full((480, 640), 2.4, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    drawer = (slice(160, 280), slice(110, 500))
    depth[drawer], color[drawer] = DEPTH_M, (150, 100, 60)
    depth[180:183, 115:495], color[180:183, 115:495] = DEPTH_M - 0.03, (230, 230, 230)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    front = find_front(Frame(0, 0.0, color, depth, K, T), np.zeros((480, 640), bool), 300, 250)
    assert front.height_m == pytest.approx(120 * DEPTH_M / K.fx, abs=0.03)


def test_a_slit_lies_below_the_surface_on_both_its_sides():
    """A handle's band off the plane (no surface cells) beside a line lower than the surface past it: one side is
    not known, so the line is no slit (before: compared with its known side alone, every edge of a handle's band
    that the depth dips at was one, and they made slits common enough to refuse the faint gaps), while a dip with
    the surface on both sides is."""
    _, judged, offset = _profile(0)
    surface = judged.copy()
    surface[50:60] = False
    offset[60] -= 0.006
    offset[90] -= 0.006
    assert np.flatnonzero(slit_lines(offset, surface, 0.0033)).tolist() == [89, 90, 91]


def test_a_door_beside_a_lower_neighbour_level_with_it_keeps_its_own_width_and_height():
    """A tall door with a lower unit beside it, their fronts in one plane, a pale bar standing out along the unit's
    edge (off the plane, wider than a gap line), a wall behind above the unit; pointed above the unit. Walked over
    the door's height, the columns run over the unit's front; the rows walked over those columns must not lose the
    door."""
    depth = np.full((480, 640), 2.4, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    door, unit = (slice(40, 440), slice(330, 450)), (slice(180, 440), slice(150, 322))
    for part in (door, unit):
        depth[part], color[part] = DEPTH_M, (150, 100, 60)
    depth[180:440, 322:330], color[180:440, 322:330] = DEPTH_M - 0.02, 240
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    front = find_front(Frame(0, 0.0, color, depth, K, T), np.zeros((480, 640), bool), 400, 80)
    assert front.width_m == pytest.approx(120 * DEPTH_M / K.fx, abs=0.03)
    assert front.height_m == pytest.approx(400 * DEPTH_M / K.fx, abs=0.03)
