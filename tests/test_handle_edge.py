"""A bar on a door's very edge (refrigerators, wardrobes) overhanging the door by most of its width: its centre lies
past the rectangle's side, its cells on it. Stub view and candidates: 1 cm cells, the rectangle 40 x 90 cm."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from deploy.perception.front_extent import Extent
from deploy.perception.handle import on_surface_side, own_blob

RES_M = 0.01


def _view() -> SimpleNamespace:
    """A plane view whose origin (the user's pixel) is cell (50, 50): col = s / RES_M + 50, row = 50 - z / RES_M."""
    return SimpleNamespace(res_m=RES_M, col=lambda s: np.round(np.asarray(s) / RES_M + 50).astype(int),
                           row=lambda z: np.round(50 - np.asarray(z) / RES_M).astype(int),
                           z=lambda row: (50 - np.asarray(row, float)) * RES_M)


def _bar(cols: tuple[int, int], rows: tuple[int, int]) -> SimpleNamespace:
    """A firm bar over the view's cells `cols` x `rows` (inclusive), along the longer of the two."""
    rr, cc = np.mgrid[rows[0]:rows[1] + 1, cols[0]:cols[1] + 1]
    centre = np.array([((cols[0] + cols[1]) / 2 - 50) * RES_M, (50 - (rows[0] + rows[1]) / 2) * RES_M])
    tall, wide = (rows[1] - rows[0] + 1) * RES_M, (cols[1] - cols[0] + 1) * RES_M
    return SimpleNamespace(firm=True, centre=centre, rows=rr.ravel(), cols=cc.ravel(),
                           axis=np.array([0.0, 1.0] if tall > wide else [1.0, 0.0]), length_m=max(tall, wide),
                           relief_m=0.04, elongation=6.0, seen_in_colour_only=False, inside=False,
                           points=np.zeros((0, 3)), across_m=min(tall, wide))


def test_a_bar_overhanging_the_doors_side_by_most_of_its_width_is_its_handle():
    """The rectangle's left side (column 30) ended where the surface stopped; the 3 cm bar spans columns 27-30, its
    centre 2.5 cm past the side, farther than an edge band (before: judged by its centre alone, no handle)."""
    extent = Extent(10, 100, 30, 70, {"top": "surface", "bottom": "surface", "left": "surface", "right": "gap"})
    bar = _bar((27, 30), (60, 76))
    bar.centre[0] -= 0.01  # its measured centre 2.5 cm past the side, its cells still on it
    assert on_surface_side(bar, _view(), extent)
    assert own_blob([bar], _view(), extent) is bar


def test_a_bar_beyond_a_gap_or_clear_of_the_side_is_not_the_fronts():
    """The same bar past a side that ended at a gap is the next front's; one whose cells stop 3 cm short of a side
    where the surface stopped stands on something else, and so does a horizontal bar whose end comes within a
    centimetre of that side (a neighbouring drawer's)."""
    extent = Extent(10, 100, 30, 70, {"top": "surface", "bottom": "surface", "left": "gap", "right": "surface"})
    assert own_blob([_bar((71, 90), (60, 62))], _view(), extent) is None
    assert own_blob([_bar((27, 30), (60, 76))], _view(), extent) is None
    assert own_blob([_bar((74, 77), (60, 76))], _view(), extent) is None
    assert own_blob([_bar((71, 74), (60, 76))], _view(), extent) is not None
