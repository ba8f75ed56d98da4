"""Where a front ends, in its rectified view: the rectangle around the user's pixel bounded by the gaps between
fronts and by the places where the front's surface stops.

Fronts are rectangles in a vertical plane. From the seed cell the rectangle grows one side at a time, along the
profile of the cells of that side's band (the rows or columns the rectangle spans so far), until one of:
- a gap: a thin line (at most GAP_LINE_M wide) darker or lighter than the surface on both sides, along most of the
  band (the slit between two fronts);
- the surface ends: more than HANDLE_BAND_M of cells off the plane (a counter's overhang, a plinth, the floor, a
  wall, a neighbour standing out). Shorter stretches are a handle, its shadow or a pocket, and are crossed, but for
  a member across the furniture: a stretch running on past both sides of the front (a counter's edge, a shelf);
- the view ends (the image's border): the side is marked cut.
Cells the camera does not see (the arm, no depth) are neither surface nor boundary: they are crossed, and so are the
cells the caller says belong to the front whatever their depth (`crossed`: a recessed pull's pocket, cut into the
panel and closed by it on every side, may run longer than HANDLE_BAND_M along a thin drawer).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import cv2
import numpy as np

from deploy.perception.plane_view import PlaneView

GAP_LINE_M = 0.006  # a gap between fronts is 2-4 mm; with a pixel of blur either side it stays under this
GAP_CONTRAST = 0.02  # a gap line differs from the surface on both sides by at least this (of full scale, averaged
# along it): a slit in shadow, or a lit carcass edge behind it; 2 % is five 8-bit levels, above the sensor's noise
GAP_SEGMENT_M = 0.03  # the line is judged per stretch of this length along it ...
GAP_SHARE = 0.5  # ... and must show in at least this share of the stretches the band sees (a handle may hide it)
GAP_MIN_STRETCHES = 2  # ... and in at least this many (or all the band has): a gap runs along a front's whole side,
# 10 cm and more, while a handle's end, a knob's shadow or a post's edge beside the surface make a line one stretch long
FAINT_CONTRAST = 0.001  # a gap lit like the fronts differs from them by less than an 8-bit level: a line this faint
# (a quarter level, averaged along a stretch) is a gap where the surface dips in depth along it (SLIT_SIGMAS)
SLIT_SIGMAS = 3.0  # a slit: the surface's depth, its median along a line, lies below both sides' by this many times
# that dip's spread over the profile's lines (the D415's noise and the plane's own waviness along the band)
CHANCE_LINES = 0.1  # faint lines and slits are taken together only while fewer than this many lines of the profile
# would be both by chance (a grain's texture makes faint lines common: one of them meets the depth's noise)
RELIEF_M = 0.01  # a handle stands at least this far out of its front (bars 25-50 mm): cells whose line stands out this
# far over a stretch are a bar too thin for the smoothed depth to leave the plane, not the surface a gap is judged on
HANDLE_BAND_M = 0.10  # the widest stretch across a front that is not its surface: a handle, its shadow, a pocket
RESUME_M = 0.04  # past a handle the front's surface goes on for at least this, or up to a gap (a surface crossing
# the plane, such as the floor at a plinth's foot, lies on it within the D415's noise for a narrower band)
MAX_SLOPE = 0.3  # a front is parallel to its plane: a surface whose offset changes faster than this (17 deg) is not
SLOPE_BASE_M = 0.01  # ... measured between lines this far either side
SURFACE_SHARE = 0.5  # a line of the band is the front's surface when at least this share of its seen cells are
MIN_SEEN_SHARE = 0.2  # a line with fewer of its cells seen says nothing
COLOUR_DELTA_E = 15.0  # a colour this far (CIE76 Delta E) from the front's is another surface's (a neighbour of
# another finish, a counter's edge) ...
TEXTURE_SPREAD = 2.0  # ... or this many times farther than the front's own texture (wood grain) spreads (its 80th
# percentile Delta E)
START_HALF_M = 0.08  # the first band: this far either side of the seed (half the narrowest drawer's width)
MEMBER_PAST_M = 0.02  # a stretch off the surface running on this far past both ends of the front's surface beside
# it is a member across the furniture (a counter's edge, a shelf), not a handle, which ends on its front


@dataclass(frozen=True)
class Extent:
    """A front's rectangle in its view's grid: rows [top, bottom] and columns [left, right] (inclusive), and what
    ended each side: "gap", "surface" (the surface stopped) or "view" (the image's border: the side is cut)."""

    top: int
    bottom: int
    left: int
    right: int
    ended: dict[str, str]


def front_extent(view: PlaneView, seed: tuple[int, int], crossed: np.ndarray | None = None,
                 through: np.ndarray | None = None) -> Extent:
    """The front's rectangle around the seed cell (row, col) of `view` (see the module docstring); `crossed`: cells
    crossed as unseen; `through`: cells crossed whatever lines they show (no gap is looked for there)."""
    half = max(int(round(START_HALF_M / view.res_m)), 2)
    r, c = seed
    surface, depth_surface = _front_cells(view, seed, crossed, through)
    rows, cols = (r, r), (c - half, c + half)
    ended: dict[str, str] = {}
    for _ in range(2):
        if _share(surface[r:r + 1, max(cols[0], 0):cols[1] + 1], None, view.res_m)[0] < SURFACE_SHARE:
            # the columns walked over the front's rows reached past its side, along rows where a surface level
            # with it goes on (a neighbour's front, its gap missed): the seed's own row bounds the columns
            (left, ended["left"]), (right, ended["right"]) = _grow(view, surface, depth_surface, seed, (r, r), 1,
                                                                   through)
            cols = (left, right)
            (top, ended["top"]), (bottom, ended["bottom"]) = _grow(view, surface, depth_surface, seed, cols, 0,
                                                                   through)
            return Extent(top, bottom, left, right, ended)
        (top, ended["top"]), (bottom, ended["bottom"]) = _grow(view, surface, depth_surface, seed, cols, 0, through)
        rows = (top, bottom)
        (left, ended["left"]), (right, ended["right"]) = _grow(view, surface, depth_surface, seed, rows, 1, through)
        cols = (left, right)
    return Extent(rows[0], rows[1], cols[0], cols[1], ended)


def rows_over_columns(view: PlaneView, seed: tuple[int, int], extent: Extent,
                      crossed: np.ndarray | None = None) -> Extent:
    """`extent` with its top and bottom walked again from the seed over its own columns only: a rectangle cut
    narrower (`front_cuts.split_wide`) had them judged over a neighbour's columns too, whose gaps (a drawer's beside
    a taller front) do not bound the seed's front."""
    surface, depth_surface = _front_cells(view, seed, crossed, None)
    (top, ended_top), (bottom, ended_bottom) = _grow(view, surface, depth_surface, seed, (extent.left, extent.right),
                                                     0, None)
    return replace(extent, top=top, bottom=bottom, ended={**extent.ended, "top": ended_top, "bottom": ended_bottom})


def _front_cells(view: PlaneView, seed: tuple[int, int], crossed: np.ndarray | None,
                 through: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(the front's cells: 1 on its plane and of its colour, 0 not, NaN unknown or crossed; the plane's surface in
    depth, `_surface`) around the seed cell. A hole of another colour is not the front, one of its colour is not
    known (a pale wall and a dark front alike lose the D415's dots)."""
    half = max(int(round(START_HALF_M / view.res_m)), 2)
    r, c = seed
    depth_surface = _surface(view)
    same = same_colour(view, (slice(max(r - half, 0), r + half + 1), slice(max(c - half, 0), c + half + 1)))
    surface = np.where(np.isnan(depth_surface) & view.seen, np.where(same > 0, np.nan, 0.0), depth_surface * same)
    for cells in (crossed, through):
        if cells is not None:
            surface[cells] = np.nan
    return surface, depth_surface


def _grow(view: PlaneView, surface: np.ndarray, depth_surface: np.ndarray, seed: tuple[int, int],
          band: tuple[int, int], axis: int, through: np.ndarray | None) -> tuple[tuple[int, str], tuple[int, str]]:
    """Both ends along `axis` (0: rows, up and down; 1: columns) of the front through `seed`, judged over the
    cells `band` (inclusive) across it: `surface` the front's cells (1, 0, NaN unknown); gaps are looked for between
    cells of the plane's surface in depth (`depth_surface`), whatever their colour, and seen cells without depth (a
    dark or pale finish loses the D415's dots in patches, a gap's slit too), but for the cells `through`."""
    lo, hi = max(band[0], 0), min(band[1], surface.shape[1 - axis] - 1)

    def cut(a: np.ndarray) -> np.ndarray:  # the band's cells, along `axis` first
        return a[:, lo:hi + 1] if axis == 0 else a[lo:hi + 1].T

    cells, flat, grey, seen, offset = cut(surface), cut(depth_surface), cut(view.gray), cut(view.seen), \
        cut(view.offset_m)
    share = _share(cells, None, view.res_m)
    raised = raised_cells(np.where(seen, offset, np.nan), cut(view.tolerance_m), view.res_m)
    judged = ((flat == 1.0) | (np.isnan(flat) & seen)) & ~raised
    if through is not None:
        judged &= ~cut(through)
    lines = gap_lines(grey, judged, view.res_m) | _faint_gaps(grey, judged, offset, (flat == 1.0) & ~raised,
                                                              view.res_m)
    start = seed[axis]
    full = surface if axis == 0 else surface.T
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # lines without depth
        level = np.nanmedian(np.where(seen, offset, np.nan), axis=1)
    return tuple(_before_member(share, full, start, seed[1 - axis],
                                _walk(share, lines, start, step, view.res_m, level), step, view.res_m)
                 for step in (-1, 1))


def _before_member(share: np.ndarray, surface: np.ndarray, start: int, centre: int, walked: tuple[int, str],
                   step: int, res_m: float) -> tuple[int, str]:
    """`walked` (the walk's end from line `start` in direction `step` over the band's `share` profile, and what
    ended it), ended instead before the first stretch off the surface it crossed (up to where the surface resumes
    for RESUME_M, as the walk takes it), past RESUME_M of the surface, that is a member across the furniture
    (`_is_member` along the lines of `surface`, the front's cells, from cell `centre`): the front ends there."""
    end, resume = walked[0], int(np.ceil(RESUME_M / res_m))
    i, on = start + step, 0
    while (end - i) * step >= 0:
        if np.isnan(share[i]) or share[i] >= SURFACE_SHARE:
            on += 0 if np.isnan(share[i]) else 1
            i += step
            continue
        first, last_off, run = i, i, 0
        while (end - i) * step >= 0 and run < resume:
            if share[i] >= SURFACE_SHARE:
                run += 1
            elif not np.isnan(share[i]):
                run, last_off = 0, i
            i += step
        before = sorted((first - step, first - step * resume))
        if on >= resume and _is_member(surface, (max(before[0], 0), before[1]), sorted((first, last_off)), centre,
                                       res_m):
            return first - step, "surface"
        on = run
    return walked


def _is_member(surface: np.ndarray, front: tuple[int, int], stretch: tuple[int, int], centre: int,
               res_m: float) -> bool:
    """Whether the lines `stretch` (inclusive) of `surface` (1 the front's cell, 0 not, NaN unknown), off the
    surface at cell `centre`, stay off it along them, unbroken, past both ends of the surface along the lines `front`
    (walked from `centre` as a front's side is, short interruptions crossed) by MEMBER_PAST_M."""
    off = np.where(np.isnan(surface), np.nan, 1.0 - surface)
    none = np.zeros(surface.shape[1], bool)
    on_share = _share(surface[front[0]:front[1] + 1].T, None, res_m)
    off_share = _share(off[stretch[0]:stretch[1] + 1].T, None, res_m)
    past = MEMBER_PAST_M / res_m
    for step in (-1, 1):
        side, member_side = _walk(on_share, none, centre, step, res_m)[0], centre
        while 0 <= member_side + step < len(off_share) and not off_share[member_side + step] < SURFACE_SHARE:
            member_side += step
        if (member_side - side) * step < past:
            return False
    return True


def same_colour(view: PlaneView, patch: tuple[slice, slice]) -> np.ndarray:
    """Per cell, 1.0 where its colour is the front's: within the larger of COLOUR_DELTA_E and TEXTURE_SPREAD times
    the front's own spread (its 80th percentile Delta E around the seed, `patch`) of the front's median colour."""
    lab = view.lab
    cells = lab[patch][view.on_plane[patch]]
    if len(cells) < 10:
        return np.ones(view.shape)
    reference = np.median(cells, axis=0)
    spread = float(np.percentile(colour_distance(cells, reference), 80))  # a handle's shadow may take a fifth
    return (colour_distance(lab, reference) <= max(COLOUR_DELTA_E, TEXTURE_SPREAD * spread)).astype(float)


def colour_distance(lab: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """CIE76 Delta E between OpenCV 8-bit Lab colours."""
    d = (lab - reference) * np.array([100.0 / 255.0, 1.0, 1.0], np.float32)
    return np.sqrt(np.sum(d * d, axis=-1))


def surface_walk(view: PlaneView, extent: Extent) -> tuple[tuple[int, str], tuple[int, str]]:
    """(row, what ended it) above and below `extent` where the surface of its columns ends, gaps crossed: the top and
    bottom of the face the front is part of."""
    cols = slice(extent.left, extent.right + 1)
    share = _share(_surface(view)[:, cols], view.smooth_m[:, cols], view.res_m)
    none = np.zeros(len(share), bool)
    return _walk(share, none, extent.top, -1, view.res_m), _walk(share, none, extent.bottom, 1, view.res_m)


def _share(cells: np.ndarray, offsets: np.ndarray | None, res_m: float) -> np.ndarray:
    """Per line of `cells` (1 surface, 0 not, NaN unknown): the share of its known cells that are the surface; 0
    where the offset from the plane of the line's surface cells (`offsets`, when given: walking up and down a whole
    face, where horizontal surfaces cross the plane) changes along the walk faster than MAX_SLOPE (the floor at a
    plinth's foot lies on the plane only over a band); NaN where too few cells are known."""
    seen = np.sum(~np.isnan(cells), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(seen >= MIN_SEEN_SHARE * cells.shape[1], np.nansum(cells, axis=1) / seen, np.nan)
    if offsets is None:
        return share
    k = max(int(round(SLOPE_BASE_M / res_m)), 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # lines with no depth at all
        level = np.nanmedian(np.where(cells == 1.0, offsets, np.nan), axis=1)  # of its surface cells only
    slope = np.full(len(level), np.nan)
    slope[k:-k] = np.abs(level[2 * k:] - level[:-2 * k]) / (2 * k * res_m)
    return np.where(slope > MAX_SLOPE, 0.0, share)


def _surface(view: PlaneView) -> np.ndarray:
    """Per cell: 1 on the plane's surface, 0 off it, NaN unknown (not seen, no depth)."""
    return np.where(view.on_plane, 1.0, np.where(view.seen & ~np.isnan(view.offset_m), 0.0, np.nan))


def _walk(share: np.ndarray, lines: np.ndarray, start: int, step: int, res_m: float,
          level: np.ndarray | None = None) -> tuple[int, str]:
    """From `start` in direction `step`: the last line of the front's surface before a gap, the surface's end or the
    profile's end, and which of these ended it. Past a handle a strip of the surface shorter than RESUME_M is the
    front's own when the surface ends at an outer edge right past it (`_edge_after` on `level`, the lines' offsets
    from the plane), where a surface crossing the plane goes on smoothly."""
    band_limit = int(np.ceil(HANDLE_BAND_M / res_m))
    resume = int(np.ceil(RESUME_M / res_m))
    last, off, on = start, 0, resume
    strip, strip_end = start, start  # the current run of the surface: its first and last lines
    i = start + step
    while 0 <= i < len(share):
        if lines[i]:  # the surface went on up to its gap
            return (i - step if on > 0 else last), "gap"
        if np.isnan(share[i]):
            i += step
            continue
        if share[i] < SURFACE_SHARE:
            off, on = off + 1, 0
            if off > band_limit:
                short = level is not None and strip_end != last and _edge_after(level, strip_end, i, step) \
                    and _drop(level, last, strip, step) is None
                return (strip_end if short else last), "surface"
        else:
            strip = i if on == 0 else strip
            on, strip_end = on + 1, i
            if on >= resume:  # the surface goes on (not a surface crossing the plane: the floor, a shelf)
                off, last = 0, i
        i += step
    return last, "view"


def _edge_after(level: np.ndarray, begin: int, end: int, step: int) -> bool:
    """Whether the lines from `begin` to `end` (in direction `step`; `level` their offsets from the plane, NaN
    unknown) drop away behind the plane by more than HANDLE_BAND_M between neighbouring known lines (the view sees
    past an outer edge: no surface the view follows falls so steeply) before any stands out of it by RELIEF_M."""
    drop = _drop(level, begin, end, step)
    between = level[min(begin, drop):max(begin, drop) + 1] if drop is not None else level[:0]
    return drop is not None and not np.any(between > RELIEF_M)


def _drop(level: np.ndarray, begin: int, end: int, step: int) -> int | None:
    """The first line from `begin` to `end` (in direction `step`) lying behind the last known line before it by more
    than HANDLE_BAND_M (`level`: the lines' offsets from the plane, NaN unknown), or None."""
    prev = level[begin]
    for j in range(begin + step, end + step, step):
        if not np.isnan(level[j]):
            if prev - level[j] > HANDLE_BAND_M:
                return j
            prev = level[j]
    return None


def gap_lines(grey: np.ndarray, surface: np.ndarray, res_m: float) -> np.ndarray:
    """Bool per line (row of `grey`): a gap line runs along it (see GAP_*) and reaches one end of it (the first or
    last stretch judged): a gap runs along a front's whole side, while the end of a recessed pull's slot or a
    panel's groove, however long, stops short of both. `surface`: the cells of the front's surface, the only ones
    judged."""
    shares, shown, stretches, at_end = _gap_stretches(grey, surface, res_m)
    return (shares >= GAP_SHARE) & (shown >= min(GAP_MIN_STRETCHES, stretches)) & at_end


def _faint_gaps(grey: np.ndarray, judged: np.ndarray, offset: np.ndarray, on_plane: np.ndarray,
                res_m: float) -> np.ndarray:
    """Bool per line: a gap too faint in colour for `gap_lines` (lit like the fronts either side) that the depth
    shows: a line of FAINT_CONTRAST along it (`judged` cells; wherever it ends: too faint to show where the
    neighbours' own edges meet it, while the slit says it runs the band) over a slit (`slit_lines` of `offset` on
    the plane's cells), on a profile where so few lines are either that a line both by chance is unlikely."""
    shares, shown, stretches, _ = _gap_stretches(grey, judged, res_m, FAINT_CONTRAST)
    faint = (shares >= GAP_SHARE) & (shown >= min(GAP_MIN_STRETCHES, stretches))
    slit = slit_lines(offset, on_plane, res_m)
    if np.sum(faint) * np.sum(slit) / max(len(faint), 1) >= CHANCE_LINES:
        return np.zeros(len(faint), bool)
    return faint & slit


def raised_cells(offset: np.ndarray, tolerance: np.ndarray, res_m: float) -> np.ndarray:
    """Bool per cell (`offset`: the depth's offset from the plane along lines, NaN where none or not seen): the median
    offset of its line over its stretch (GAP_SEGMENT_M) stands out of the plane by RELIEF_M and the noise band
    (`tolerance`): a bar across the front, whose thin relief the smoothed depth averages into the plane, while its
    outline and shadow draw lines in colour."""
    n_lines, length = offset.shape
    segment = max(int(round(GAP_SEGMENT_M / res_m)), 4)
    usable = max(length // segment, 1) * segment
    raised = np.zeros(offset.shape, bool)
    if usable > length:
        return raised
    parts = offset[:, :usable].reshape(n_lines, -1, segment)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # stretches without depth
        level = np.repeat(np.nanmedian(parts, axis=2), segment, axis=1)
    with np.errstate(invalid="ignore"):
        raised[:, :usable] = level >= np.maximum(RELIEF_M, tolerance[:, :usable])
    return raised


def slit_lines(offset: np.ndarray, surface: np.ndarray, res_m: float) -> np.ndarray:
    """Bool per line (row of `offset`, the depth's offset from the plane): the front's surface (`surface`, cells
    on the plane: a handle, a knob or a pull's pocket left out) dips along it, or along a line beside it, below the
    lines on both sides past a gap line's width by SLIT_SIGMAS times the spread of that dip over the lines: the slit
    between two fronts, which the D415 sees into over a few millimetres however faintly it shows in colour."""
    n_lines, length = offset.shape
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # lines with no surface cell
        level = np.nanmedian(np.where(surface, offset, np.nan), axis=1)
    level[np.sum(surface, axis=1) < MIN_SEEN_SHARE * length] = np.nan
    k = max(int(round(GAP_LINE_M / res_m)), 1) + 1  # the sides, past the line's half-width and blur
    padded = np.concatenate([np.full(k + 2, np.nan), level, np.full(k + 2, np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 3)  # window j: padded[j:j + 3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # sides beyond the profile
        sides = np.nanmedian(windows, axis=1)
        dip = np.minimum(sides[:n_lines], sides[2 * k + 2:2 * k + 2 + n_lines]) - level
        near = np.nanmax(np.stack([np.roll(dip, 1), dip, np.roll(dip, -1)]), axis=0)
    known = near[~np.isnan(near)]
    if len(known) < 10:
        return np.zeros(n_lines, bool)
    centre = np.median(known)
    spread = 1.4826 * np.median(np.abs(known - centre))  # robust: the gaps and edges are few of the lines
    with np.errstate(invalid="ignore"):
        return near - centre >= SLIT_SIGMAS * spread


def gap_line_shares(grey: np.ndarray, surface: np.ndarray, res_m: float) -> np.ndarray:
    """Per line (row of `grey`): the share of its judged stretches (GAP_SEGMENT_M long) along which a thin line of
    GAP_CONTRAST runs (0 where none is judged). `surface`: the cells of the front's surface, the only ones judged."""
    return _gap_stretches(grey, surface, res_m)[0]


def long_gap_line_shares(grey: np.ndarray, surface: np.ndarray, res_m: float) -> np.ndarray:
    """As `gap_line_shares`, 0 for lines shown along fewer than GAP_MIN_STRETCHES stretches (a handle's end, a
    knob's shadow)."""
    shares, shown, _, _ = _gap_stretches(grey, surface, res_m)
    return np.where(shown >= GAP_MIN_STRETCHES, shares, 0.0)


def _gap_stretches(grey: np.ndarray, surface: np.ndarray, res_m: float,
                   contrast: float = GAP_CONTRAST) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """(per line: the best share of judged stretches showing a gap line of `contrast`, how many stretches show it at
    that share; the number of stretches along a line; per line, whether the first or last judged stretch shows it
    at that share): see `gap_line_shares`."""
    n_lines, length = grey.shape
    widest = max(int(round(GAP_LINE_M / res_m)), 1)
    segment = max(int(round(GAP_SEGMENT_M / res_m)), 4)
    n_seg = max(length // segment, 1)
    usable = min(n_seg * segment, length)
    reach = widest + 2  # the line's sides must be the front's surface this far out: not a handle's or a shadow's edge
    judged = cv2.erode(surface.astype(np.uint8), np.ones((2 * reach + 1, 1), np.uint8)).astype(bool)
    g = np.where(surface, grey, np.nan)[:, :usable]
    g_judged = judged[:, :usable]
    best, best_shown, best_end = np.zeros(n_lines), np.zeros(n_lines, int), np.zeros(n_lines, bool)
    for k in range(1, widest + 1):  # the line's half-width plus one: its sides are k lines away
        before, after = np.full_like(g, np.nan), np.full_like(g, np.nan)
        before[k:], after[:-k] = g[:-k], g[k:]
        for sign in (1.0, -1.0):  # darker or lighter than both sides
            response = np.where(g_judged, np.fmin(sign * (before - g), sign * (after - g)), np.nan)
            with np.errstate(invalid="ignore"):
                per_segment = _segment_means(response, n_seg)
                shown = np.sum(per_segment >= contrast, axis=1)
                judged_segments = np.sum(~np.isnan(per_segment), axis=1)
            share = shown / np.maximum(judged_segments, 1)
            at_end = _shown_at_an_end(response, per_segment, n_seg, contrast)
            better = share > best
            best, best_shown = np.where(better, share, best), np.where(better, shown, best_shown)
            best_end = np.where(better, at_end, best_end)
    return best, best_shown, n_seg, best_end


def _shown_at_an_end(response: np.ndarray, per_segment: np.ndarray, n_seg: int, contrast: float) -> np.ndarray:
    """Per line: whether the line shows along most of the first or the last of its judged stretches (the median
    response there at least `contrast`: a line ending inside that stretch does not reach the end)."""
    n_lines, length = response.shape
    judged = ~np.isnan(per_segment)
    lines = np.arange(n_lines)
    parts = response.reshape(n_lines, n_seg, length // n_seg)
    shown = np.zeros(n_lines, bool)
    for end in (np.argmax(judged, axis=1), n_seg - 1 - np.argmax(judged[:, ::-1], axis=1)):
        with warnings.catch_warnings(), np.errstate(invalid="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)  # lines with no judged cell there
            shown |= np.nanmedian(parts[lines, end], axis=1) >= contrast
    return shown


def _segment_means(response: np.ndarray, n_seg: int) -> np.ndarray:
    """Mean of `response` over each of `n_seg` equal stretches of every line (NaN where a stretch has no value)."""
    n_lines, length = response.shape
    parts = response.reshape(n_lines, n_seg, length // n_seg)
    counts = np.sum(~np.isnan(parts), axis=2)
    sums = np.nansum(parts, axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts >= 2, sums / counts, np.nan)
