"""A frame-and-panel front (a shaker door): its panel is set back into a frame of stiles and rails a few millimetres
to two centimetres proud of it, and its handle is mounted on a stile. The plane at a pixel on the panel is the
panel's, and the rectangle grown on it (front_extent.py) stops at the frame, whose surface leaves that plane.

Past a side of that rectangle the frame shows as a strip: the surface rises out of the plane by a set-back within
a smoothing window of the side, stays out by at most a panel's set-back over a stile's width, and falls where the
front ends (its gap, or what lies behind its edge). A neighbour standing out is wider than a stile, a counter's edge
stands out farther than a panel is set back, and a coplanar neighbour does not rise at all. The frame's level along a
side is its lower quartile: a handle on the stile stands out of it over less than its length.
"""

from __future__ import annotations

import warnings

import numpy as np

from deploy.perception.front_extent import Extent
from deploy.perception.plane_view import SMOOTH_CELLS, PlaneView

FRAME_STEP_M = 0.004  # a frame stands at least this proud of its panel (real ones 6-20 mm) ...
MAX_SET_BACK_M = 0.02  # ... and at most this (a handle stands 25-50 mm out, a counter's edge more)
STILE_M = (0.03, 0.12)  # stiles and rails are this wide (real ones 5-10 cm; models scaled down narrower)
PANEL_M = 0.01  # the panel's level beside a side: its lines this far inside, past the smoothing window
SPAN_SHARE = 0.8  # a side's lines are judged over this middle share of its span (the corners meet the other sides)


def framed_panel(view: PlaneView, extent: Extent) -> tuple[Extent, float] | None:
    """When the rectangle `extent` is a panel set into its front's frame: the rectangle grown over the frame's strips
    past its sides (each such side then ends at the "frame"'s edge) and the frame's offset from the plane (m, the
    strips' median level); None when no side shows one (see the module docstring)."""
    grown = {"top": extent.top, "bottom": extent.bottom, "left": extent.left, "right": extent.right}
    ended, levels = dict(extent.ended), []
    for side, step in (("top", -1), ("bottom", 1), ("left", -1), ("right", 1)):
        if extent.ended.get(side) == "view":
            continue
        strip = _strip(_side_profile(view, extent, side), grown[side], step, view.res_m)
        if strip is not None:
            grown[side], level = strip
            ended[side] = "frame"
            levels.append(level)
    if not levels:
        return None
    return Extent(grown["top"], grown["bottom"], grown["left"], grown["right"], ended), float(np.median(levels))


def _side_profile(view: PlaneView, extent: Extent, side: str) -> np.ndarray:
    """Per line across `side` (rows for top and bottom, columns for left and right, over the whole view): the lower
    quartile of the offsets from the plane of its seen cells with depth over the middle SPAN_SHARE of the side's span
    (NaN with none)."""
    horizontal = side in ("top", "bottom")
    lo, hi = (extent.left, extent.right) if horizontal else (extent.top, extent.bottom)
    trim = int((hi - lo + 1) * (1 - SPAN_SHARE) / 2)
    span = slice(lo + trim, hi - trim + 1)
    offset, seen = (a[:, span] if horizontal else a[span].T for a in (view.smooth_m, view.seen))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # lines with no depth
        return np.nanpercentile(np.where(seen, offset, np.nan), 25, axis=1)


def _strip(lines: np.ndarray, side: int, step: int, res_m: float) -> tuple[int, float] | None:
    """(the strip's outermost line, its level) when the profile `lines` rises out of the panel's level past line
    `side` (walking in direction `step`) into a frame's strip: within a smoothing window of the side, FRAME_STEP_M
    to MAX_SET_BACK_M above the panel, STILE_M wide, and ended by a fall of at least FRAME_STEP_M below its level (or
    lines without depth: a gap's dark slit); None otherwise."""
    ramp = SMOOTH_CELLS
    inside = side - step * (ramp + np.arange(max(int(round(PANEL_M / res_m)), 2)))
    if inside.min() < 0 or inside.max() >= len(lines) or np.isnan(lines[inside]).any():
        return None
    panel = float(np.median(lines[inside]))
    narrow, wide = (int(round(m / res_m)) for m in STILE_M)
    ahead = side + step * np.arange(1, ramp + wide + ramp + 1)
    ahead = ahead[(ahead >= 0) & (ahead < len(lines))]
    rise = lines[ahead] - panel
    raised = (rise >= FRAME_STEP_M) & (rise <= MAX_SET_BACK_M)
    if not raised[:ramp].any():
        return None
    first = int(np.argmax(raised))
    run = first + int(np.argmin(np.append(raised[first:], False)))  # one past the strip's last line
    level = float(np.median(rise[first:run]))
    if not narrow <= run - first <= wide:
        return None
    beyond = rise[run:run + ramp]
    if not (np.isnan(beyond) | (beyond <= level - FRAME_STEP_M)).any():
        return None
    return int(ahead[run - 1]), level + panel
