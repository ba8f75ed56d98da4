"""The pointed front's own surface along the seed's row of a rectified view, as a correction of the view's plane.

The view's plane is fitted to the depth over half a metre around the pixel (front.py). Seen from above, a thin
front right under a slab (a desk's drawer under its top, a rail between them) shares that half metre with faces
standing out a few centimetres: the fit averages them, and the plane may run a centimetre or more in front of the
front at the seed and turn a few degrees from it; the front's extent, walked on cells within the noise of the plane,
then ends at the seed. The front and the plane are both vertical, so the
front's surface along the plane's rows is a line in (s, offset): level + slope * s. It is fitted to the seed's own
rows only (ROW_BAND_M either side: the slab and the rail above or below are other rows), growing from the seed
(REACH_M) and keeping, at each reach, the cells within the D415's noise of the line so far (the front's neighbours
along the row, a handle, a leg, are off it).
"""

from __future__ import annotations

import numpy as np

from deploy.perception.plane_view import PlaneView

ROW_BAND_M = 0.01  # the rows fitted: this far above and below the seed (the thinnest fronts are 6-8 cm tall)
REACH_M = (0.02, 0.05, 0.1, 0.2, 0.4)  # the line is fitted out to these distances from the seed in turn
MIN_CELLS = 20  # a fit needs at least this many cells on the line


def seed_surface(view: PlaneView, seed: tuple[int, int]) -> tuple[float, float] | None:
    """(level m, slope) of the front's surface along the seed's rows (see the module docstring), relative to the
    view's plane (offset = level + slope * (s - s_seed)), when it lies behind the plane at the seed beyond the noise.
    None when the plane lies on it there (a plane on the seed's surface but turned from it is kept: it bounds a
    front set in an apron, whose stiles the walk would cross, no worse than the apron's ends), when it stands out of
    the plane (a handle or a knob at the pixel: the plane is its front's), or when too little of it is seen."""
    r, c = seed
    band = max(int(round(ROW_BAND_M / view.res_m)), 1)
    rows = slice(max(r - band, 0), r + band + 1)
    offset = view.offset_m[rows]
    tolerance = view.tolerance_m[rows]
    s = np.broadcast_to(view.s(np.arange(view.shape[1])) - view.s(c), offset.shape)
    known = view.seen[rows] & ~np.isnan(offset)
    near = known & (np.abs(s) <= REACH_M[0])
    if np.count_nonzero(near) < MIN_CELLS:
        return None
    level, slope = float(np.median(offset[near])), 0.0
    reach = REACH_M[0]
    for reach in REACH_M:
        with np.errstate(invalid="ignore"):
            on = known & (np.abs(s) <= reach) & (np.abs(offset - level - slope * s) <= tolerance)
        if np.count_nonzero(on) < MIN_CELLS:
            break
        slope, level = np.polyfit(s[on], offset[on], 1)
        slope, level = float(slope), float(level)
    with np.errstate(invalid="ignore"):
        tol = float(np.nanmedian(tolerance[near]))
    if abs(level) <= tol or level > 0:
        return None
    return level, slope
