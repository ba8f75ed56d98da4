"""The walk along a front's profile past its handle: a strip of the surface shorter than RESUME_M ends the front when
the view sees past an outer edge right beyond it, and not when the surface beyond goes on smoothly or stands out."""

from __future__ import annotations

import numpy as np

from deploy.perception.front_extent import _walk

RES_M = 0.0025


def _profile(beyond: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(share, level) walking up from line 0: 20 lines of surface, a bar 6 lines standing out 20 mm, a strip of the
    surface 8 lines (2 cm) long, then the lines `beyond` (their offsets from the plane; off the surface)."""
    share = np.concatenate([np.ones(20), np.zeros(6), np.ones(8), np.zeros(len(beyond))])
    level = np.concatenate([np.zeros(20), np.full(6, 0.02), np.zeros(8), beyond])
    return share, level


def _top(beyond: np.ndarray) -> int:
    share, level = _profile(beyond)
    return _walk(share, np.zeros(len(share), bool), 0, 1, RES_M, level)[0]


def test_a_short_strip_past_the_handle_ending_at_an_outer_edge_is_the_fronts_own():
    assert _top(np.concatenate([np.full(2, -0.004), np.full(60, -0.6)])) == 33


def test_a_short_strip_is_not_the_fronts_where_the_surface_beyond_recedes_smoothly_or_stands_out():
    receding = -0.004 * np.arange(1, 61)  # a top seen from above, crossing the plane
    standing = np.concatenate([np.full(4, 0.03), np.full(60, -0.6)])  # an overhang in front, the wall past it
    assert _top(receding) == 19
    assert _top(standing) == 19
