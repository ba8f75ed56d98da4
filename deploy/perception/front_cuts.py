"""Cutting a front's rectangle where the gaps between fronts were not seen: between the handles it holds (each
front carries one) and, for one wider than fronts are, at the faintest gap lines.

Pure functions of the rectified view (plane_view.py), the rectangle (front_extent.py) and the handle candidates
(handle_blobs.py).
"""

from __future__ import annotations

import warnings

import numpy as np

from deploy.perception.front_extent import Extent, gap_line_shares, long_gap_line_shares
from deploy.perception.handle import EDGE_BAND_M, on_surface_side, spills_over_edge, tab_over_top
from deploy.perception.handle_blobs import STEP_WINDOW_M, Blob, bounds, segment_distance, span_m
from deploy.perception.plane_view import PlaneView

WEAK_GAP_SHARE = 0.25  # between two handles a line showing a gap along this share of its length is the gap
HANDLE_CLEARANCE_M = 0.02  # ... at least this far from either handle (its edge, its shadow)
EDGE_STEP_M = 0.01  # a front's edge is straight to a cell or two: where the rectangle's edge steps by this much
# between two handles, two fronts whose edges do not line up meet (units of different heights side by side)
EDGE_WINDOW_M = 0.05  # ... the edge's place per line looked for this far either side of the rectangle's side
WIDE_FRONT_M = 1.0  # fronts are rarely wider: a rectangle wider than this is looked over for the faint gaps of
# fronts side by side
NARROW_FRONT_M = 0.1  # ... each at least this wide (the narrowest drawer or door)


def split_by_handles(view: PlaneView, extent: Extent, blobs: list[Blob]) -> Extent:
    """The rectangle cut between the seed's handle and every other handle on it (or spilling over its top or bottom
    edge: `spills_over_edge`, or on its very side edge: `on_surface_side`): each front carries one, so a rectangle
    holding several spans more than one front (the gaps between them were not seen). Each cut runs across the
    direction that separates two handles (either, for two handles apart both ways: one of them separates their
    fronts), along the faint gap between them if one shows, else midway; the seed's handle is the nearest one on the
    seed's (the view's origin's) side of a cut from every other."""
    inside = [b for b in blobs if (b.inside or spills_over_edge(b, view, extent) or tab_over_top(b, view, extent)
                                   or on_surface_side(b, view, extent))
              and b.firm and (b.length_m < 0.95 * span_m(view, extent, b.axis) or _standing_bar(b, view, extent))]
    if len(inside) < 2:
        return extent
    seed = np.zeros(2)
    ranked = sorted(inside, key=lambda b: segment_distance(b, seed))
    drop = None  # how far below a seen top edge the topmost handle sits (none above it: not a tab over the edge)
    if extent.ended.get("top") in ("surface", "gap"):
        drop = float(view.z(extent.top)) - max(float(b.centre[1]) for b in inside)
        drop = drop if drop > 0 else None
    for own in ranked:
        cuts = [_seed_cut(view, _handle_cuts(view, extent, own, other, drop)) for other in inside if other is not own]
        if all(cut is not None for cut in cuts):
            break
    else:
        return extent
    top, bottom, left, right = extent.top, extent.bottom, extent.left, extent.right
    ended = dict(extent.ended)
    for side, line in cuts:
        if side == "right" and line < right:
            right, ended["right"] = line, "handle"
        elif side == "left" and line > left:
            left, ended["left"] = line, "handle"
        elif side == "top" and line > top:
            top, ended["top"] = line, "handle"
        elif side == "bottom" and line < bottom:
            bottom, ended["bottom"] = line, "handle"
    return Extent(top, bottom, left, right, ended)


def split_wide(view: PlaneView, extent: Extent) -> Extent:
    """The rectangle, while wider than WIDE_FRONT_M, cut at the column most of whose length shows a faint gap (at
    least WEAK_GAP_SHARE of it, in more than one stretch), keeping the seed's side: fronts side by side whose gaps
    showed too faintly to end the rectangle (a slit narrower than a cell). Cuts leave NARROW_FRONT_M either side."""
    seed = int(view.col(0.0))
    left, right, ended = extent.left, extent.right, dict(extent.ended)
    judged = view.on_plane | view.no_depth  # the surface, and cells without depth (patches, a slit)
    rows = slice(max(extent.top, 0), extent.bottom + 1)
    shares = long_gap_line_shares(view.gray[rows].T, judged[rows].T, view.res_m)
    keep = int(round(NARROW_FRONT_M / view.res_m))
    while (right - left) * view.res_m > WIDE_FRONT_M:
        lines = np.arange(left + keep, right - keep + 1)
        lines = lines[np.abs(lines - seed) >= keep // 2]
        if len(lines) == 0 or shares[lines].max() < WEAK_GAP_SHARE:
            break
        line = int(lines[np.argmax(shares[lines])])
        if line > seed:
            right, ended["right"] = line - 1, "gap"
        else:
            left, ended["left"] = line + 1, "gap"
    return Extent(extent.top, extent.bottom, left, right, ended)


def _standing_bar(blob: Blob, view: PlaneView, extent: Extent) -> bool:
    """Whether a candidate about as long as the rectangle is across is still a handle: it stands out of the plane in
    depth (a full-width bar; an edge, its shadow or a gap's slit do not) and runs past neither of the rectangle's ends
    by more than an edge band."""
    return blob.relief_m > 0 and not blob.seen_in_colour_only and \
        blob.length_m <= span_m(view, extent, blob.axis) + 2 * EDGE_BAND_M


def _handle_cuts(view: PlaneView, extent: Extent, own: Blob, other: Blob,
                 drop: float | None) -> list[tuple[str, int]]:
    """The cuts that may part `own`'s front from `other`'s, each (the side of `own`'s front it bounds, its row or
    column): across the direction the handles lie farther apart along, then, for handles apart both ways (fronts
    diagonal to each other), across the other. With no gap seen, side by side fronts are cut midway; stacked ones,
    where the lower handle sits as far below its front's top as the topmost handle sits below the rectangle's seen
    top edge (`drop`; handles sit alike on a stack's fronts, centred or near the top), at most midway."""
    s0, s1, z0, z1 = bounds(own, view)
    o0, o1, p0, p1 = bounds(other, view)
    mid = (own.centre + other.centre) / 2
    apart_s, apart_z = max(o0 - s1, s0 - o1), max(p0 - z1, z0 - p1)
    right = other.centre[0] > own.centre[0]
    col = _cut(view, extent, (s1, o0) if right else (o1, s0), mid[0], 1)
    beside = ("right" if right else "left"), col
    above = other.centre[1] > own.centre[1]
    lower = min(own.centre[1], other.centre[1])
    guess = mid[1] if drop is None else min(lower + drop, mid[1])
    row = _cut(view, extent, (p0, z1) if above else (z0, p1), guess, 0)
    stacked = ("top" if above else "bottom"), row
    cuts = [beside, stacked] if apart_s >= apart_z else [stacked, beside]
    return cuts if min(apart_s, apart_z) > 0 else cuts[:1]


def _seed_cut(view: PlaneView, cuts: list[tuple[str, int]]) -> tuple[str, int] | None:
    """The first of `cuts` with the seed on the front's side of it; None when it lies past all of them."""
    return next((cut for cut in cuts if _seed_side(view, *cut)), None)


def _seed_side(view: PlaneView, side: str, line: int) -> bool:
    """Whether the seed lies on the front's side of a cut bounding its `side`."""
    row, col = int(view.row(0.0)), int(view.col(0.0))
    return {"right": col < line, "left": col > line, "top": row > line, "bottom": row < line}[side]


def _cut(view: PlaneView, extent: Extent, between: tuple[float, float], guess: float, axis: int) -> int:
    """Where to cut the rectangle `extent` between two handles: the line (a row for axis 0, a column for 1, over the
    rectangle's cells across it) between the handles' facing edges (`between`, plane coordinates) most of whose
    length shows a gap, at least WEAK_GAP_SHARE of it; else, side by side, where the rectangle's top or bottom edge
    steps (`_edge_step`); else the line through `guess` (plane coordinate), kept off the handles."""
    index = view.row if axis == 0 else view.col
    ends = tuple(sorted(int(i) for i in index(np.array(between))))
    margin = max(int(round(HANDLE_CLEARANCE_M / view.res_m)), 1)  # not a handle's own edge or shadow
    a, b = ends[0] + margin, ends[1] - margin
    if b <= a:
        return int(index(guess))
    step = _edge_step(view, extent, ends) if axis == 1 else None
    fallback = int(np.clip(index(guess), a, b)) if step is None else step
    lo, hi = (max(extent.left, 0), extent.right + 1) if axis == 0 else (max(extent.top, 0), extent.bottom + 1)
    judged = view.on_plane | view.no_depth  # the surface, and cells without depth (patches, a slit)
    surface = judged[:, lo:hi] if axis == 0 else judged[lo:hi].T
    grey = view.gray[:, lo:hi] if axis == 0 else view.gray[lo:hi].T
    pad = min(a, 8)  # the lines beyond either end give the first and last lines their sides
    shares = gap_line_shares(grey[a - pad:b + 8], surface[a - pad:b + 8], view.res_m)[pad:pad + b - a]
    if len(shares) == 0:
        return fallback
    best = int(np.argmax(shares))
    return a + best if shares[best] >= WEAK_GAP_SHARE else fallback


def _edge_step(view: PlaneView, extent: Extent, ends: tuple[int, int]) -> int | None:
    """The first column past a step, between two handles side by side (`ends`: their facing edges' columns), of the
    rectangle's top or bottom edge where it ended at a gap or where the surface stopped: two units of different
    heights meet there. (Stacked fronts share their sides, one carcass's, so a side tells nothing of where they
    meet.) The edge's place per column is its outermost cell on the plane within EDGE_WINDOW_M of the rectangle's
    edge (none where the surface runs on past that window: no edge is seen there); it steps where its medians over
    STEP_WINDOW_M either side differ most, and its medians over the whole stretches either side, up to the handles,
    differ the same way by EDGE_STEP_M. None when no edge steps."""
    on, seen = view.on_plane, view.seen
    sides = (("top", extent.top, -1), ("bottom", extent.bottom, 1))
    reach = int(round(EDGE_WINDOW_M / view.res_m))
    window = max(int(np.ceil(STEP_WINDOW_M / view.res_m)), 2)
    least = EDGE_STEP_M / view.res_m
    lines = np.arange(max(ends[0], 0), min(ends[1], on.shape[1] - 1) + 1)
    at = np.arange(window, len(lines) - window + 1)
    if len(at) == 0:
        return None
    best = None
    for side, line, outward in sides:
        if extent.ended.get(side) not in ("gap", "surface"):
            continue
        r0, r1 = max(line - reach, 0), min(line + reach + 1, on.shape[0])
        band = on[r0:r1, lines]
        place = np.arange(r0, r1)[:, None] * outward  # the larger, the farther out
        edge = np.where(band, place, -np.inf).max(axis=0)
        edge = np.where(band.any(axis=0) & seen[r0:r1, lines].all(axis=0) & (edge < place.max()), edge, np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # stretches the arm hides
            local = np.array([np.nanmedian(edge[k:k + window]) - np.nanmedian(edge[k - window:k]) for k in at])
            if np.all(np.isnan(local)):
                continue
            k = int(at[np.nanargmax(np.abs(local))])
            level = np.nanmedian(edge[k:]) - np.nanmedian(edge[:k])
        if abs(level) >= least and level * local[k - at[0]] > 0 and (best is None or abs(level) > best[0]):
            best = abs(level), int(lines[k])
    return None if best is None else best[1]
