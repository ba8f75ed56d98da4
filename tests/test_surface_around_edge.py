"""The front's surface around a handle candidate at the view's border (deploy/perception/handle_blobs.py)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from deploy.perception.front_extent import Extent
from deploy.perception.handle_blobs import JOIN_M, _surface_around


def test_a_candidate_at_the_views_border_reads_the_surface_within_the_view():
    """A candidate in the view's last columns and rows: the ring around it is cut by the border, the cells inside
    give the surface's offset."""
    offset = np.full((20, 30), 0.004, np.float32)
    view = SimpleNamespace(res_m=JOIN_M, offset_m=offset, seen=np.ones(offset.shape, bool))
    rows, cols = np.array([18, 19, 19]), np.array([29, 28, 29])
    extent = Extent(0, 19, 0, 29, {})
    assert _surface_around(view, rows, cols, extent) == np.float32(0.004)
