"""Handle candidates on a front's rectified view: what stands out of the front's surface (or sinks into a pocket) in
a handle's size, or, where the D415 has no depth (thin, dark and shiny handles), differs from the front's colour.

A blob's geometry comes from its measured points where it has depth (their plane coordinates: no parallax) and
from its cells where it has none (the ray's meeting with the plane).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from deploy.perception.front_extent import COLOUR_DELTA_E, Extent, colour_distance
from deploy.perception.plane_view import QUANTUM_M, SMOOTH_NOISE, PlaneView

MAX_STANDOFF_M = 0.10  # handles stand at most this far out of their front (real bars 25-50 mm, knobs up to 40 mm)
MAX_POCKET_M = 0.05  # a recessed pull's pocket is at most this deep
MIN_SIZE_M = 0.015  # the smallest handle (a small knob's head)
MAX_ACROSS_M = 0.10  # across its length a handle, or a pull's pocket, is at most hand-sized
MAX_LENGTH_M = 1.2  # along it, at most a wide front's width
STRUCTURE_SHARE = 0.8  # a row or column standing out along this share of the search region (a front and a margin
# either side) is the structure around the front (a counter's edge, the floor), not a handle, which is shorter
JOIN_M = 0.01  # pieces of one handle closer than this are one (a bar, its posts and its depth holes)
POCKET_INSET_M = 0.02  # a pocket is cut into the panel, with material around it: at least this far inside its edges
PLINTH_SHARE = 0.8  # a pocket low on the front, running on to its edges along this share of its width, is the
# plinth's recess under the front (a pull is cut into the panel, with material around it)
EDGE_BAND_M = 0.02  # a pull standing on the front's top or bottom edge is an edge pull; a bar across a whole
# front may run this far past its ends
EDGE_REACH_M = 0.05  # an edge pull stands out of its front's edge: blobs this close outside the rectangle count


MIN_RELIEF_M = 0.01  # a handle stands at least this far out of its front (bars 25-50 mm, knobs and cups 20-40 mm,
# edge pulls 15-30 mm), or a pocket sinks at least this far in
MIN_POINTS = 8  # a candidate with fewer measured points is seen in colour only
RELIEF_NOISE = 1.2  # ... and at least this many times the depth noise band there (points just outside the band
# are noise as often as not)
FIRM_LENGTH_M = 0.025  # the smallest real knob's diameter
BAR_ELONGATION = 3.0  # a bar is at least this many times longer than thick (real bars 8-40x; cups 2-3x): a
# shorter candidate is a knob, a cup or a pull
MIN_POCKET_ACROSS_M = 0.02  # a pull's pocket takes a fingertip (real ones 25-80 mm across): a narrower slit sunk
# into the front is a seam, a gap between fronts or the depth's noise
KNOB_MAX_M = 0.06  # a knob is at most this wide (real knobs 20-50 mm)
OUTER_LAYER_M = 0.008  # a handle's front surface: its points this close to its outermost (a bar's radius)
STEP_M = 0.005  # a handle's outline runs straight along it: both its edges stepping the same way by more than this
# (and two cells: the outline's jitter) is two handles side by side at different heights (the tabs on the facing
# edges of two fronts)
STEP_WINDOW_M = 0.02  # an edge's step is sought over this stretch either side (a finger pad's width); a handle's end
# (rounded, seen at a slant) takes at most this much of its length
RIM_SHARE = 0.6  # a handle sits on its front: at least this share of the ring around it (where depth is measured,
# and, for one measured standing out, not the room seen past the front's edges) is the front's surface


@dataclass(frozen=True)
class Blob:
    """One handle candidate: its cells in the view (`rows`, `cols`), the plane coordinates (s, z, offset) of its
    measured points (`points`, (N, 3); N may be 0), `inside`: whether its centre lies inside the front's rectangle."""

    rows: np.ndarray
    cols: np.ndarray
    points: np.ndarray
    centre: np.ndarray  # (s, z) m: the middle of its extent
    axis: np.ndarray  # (2,) unit, in (s, z): along its length
    length_m: float
    across_m: float
    inside: bool
    rim: float  # the share of the ring around it that is the front's surface
    noise_m: float  # the D415's noise band there (NOISE_SIGMAS sigmas of one measurement)
    base_m: tuple[float, float] = (0.0, 0.0)  # the surface around it, offset from the plane (`_surface_around`: a
    # bowed panel, a window set in)
    depth_share: float = 0.0  # the share of its cells with depth

    @property
    def relief_m(self) -> float:
        """How far it stands out of the front (negative: sunk into it), the median of its measured points."""
        return float(np.median(self.points[:, 2])) if len(self.points) else 0.0

    @property
    def seen_in_colour_only(self) -> bool:
        """Whether the D415 measured (almost) none of it: a thin, dark or shiny handle found by its colour, most of
        its cells without depth. Cells with depth but (almost) no points out of the plane's noise were measured on the
        front's surface: a candidate found against the front's fitted surface where that turns off the plane."""
        return len(self.points) < MIN_POINTS and self.depth_share < 0.5

    @property
    def firm(self) -> bool:
        """Whether it is certainly a handle (not depth noise, not a neighbour's edge): large enough, with the front
        around it, standing clearly out of (or into, in a pocket wide enough for a fingertip) the front, or of another
        colour where depth has a hole."""
        low, high = self.base_m
        rise = abs(self.relief_m) - max(0.0, low if self.relief_m > 0 else -high)  # out of (into) the
        # surface around it: a bump on a bowed panel, or a piece of a recessed window, is off the plane with it
        relief = self.seen_in_colour_only or rise >= max(MIN_RELIEF_M, RELIEF_NOISE * self.noise_m)
        slit = self.relief_m < 0 and self.across_m < MIN_POCKET_ACROSS_M
        sliver = self.elongation < BAR_ELONGATION and self.across_m < MIN_SIZE_M  # too short for a bar, too thin
        # for a knob's head: the depth's noise or a seam
        return self.length_m >= FIRM_LENGTH_M and relief and not slit and not sliver and self.rim >= RIM_SHARE

    @property
    def elongation(self) -> float:
        return self.length_m / max(self.across_m, 1e-3)


def front_colour(view: PlaneView, extent: Extent) -> np.ndarray:
    """The front's colour (Lab, OpenCV's 8-bit scale): the median over its surface's cells."""
    sl = (slice(extent.top, extent.bottom + 1), slice(extent.left, extent.right + 1))
    cells = view.lab[sl][view.on_plane[sl]]
    return np.median(cells, axis=0) if len(cells) else np.median(view.lab[sl].reshape(-1, 3), axis=0)


def front_surface(view: PlaneView, extent: Extent, rows: slice, cols: slice) -> np.ndarray:
    """The front's surface (its offset from the plane, m) over the view's `rows` and `cols`: the plane fitted (least
    squares in the view's rows and columns) to the rectangle `extent`'s cells on the plane, then again to its cells
    within the noise band of that fit. The plane found at the pointed pixel may lie a few millimetres off the front or
    turn a degree or two from it, which across a wide front is more than the noise band; handles stand out of the
    front's surface. Starting from the plane's own cells keeps to its surface (a panel set back into its frame, a
    plinth's recess or a pull's pocket lie beyond the band). The offsets are those beyond QUANTUM_M of the plane."""
    sl = (slice(extent.top, extent.bottom + 1), slice(extent.left, extent.right + 1))
    grid_r, grid_c = np.meshgrid(np.arange(rows.start, rows.stop) - extent.top,
                                 np.arange(cols.start, cols.stop) - extent.left, indexing="ij")
    r, c = np.nonzero(view.seen[sl] & ~np.isnan(view.smooth_m[sl]))
    offsets, tolerance = view.smooth_m[sl][r, c].astype(float), view.tolerance_m[sl][r, c]
    design = np.stack([np.ones(len(r)), r, c], axis=1).astype(float)
    keep = np.abs(offsets) <= tolerance
    for _ in range(3):
        if np.count_nonzero(keep) < 3 * MIN_POINTS:
            return np.zeros(grid_r.shape)
        coef = np.linalg.lstsq(design[keep], offsets[keep], rcond=None)[0]
        keep = np.abs(design @ coef - offsets) <= tolerance
    fitted = coef[0] + coef[1] * grid_r + coef[2] * grid_c
    return np.sign(fitted) * np.maximum(np.abs(fitted) - QUANTUM_M, 0.0)  # the noise band allows the plane's fit
    # QUANTUM_M of error: only what lies beyond it is the plane's error


def handle_blobs(view: PlaneView, extent: Extent, camera_to_base: np.ndarray, K: np.ndarray) -> list[Blob]:
    """The handle candidates on the front `extent` of `view` and just outside its edges (edge pulls)."""
    reach = int(np.ceil(EDGE_REACH_M / view.res_m))
    r0, r1 = max(extent.top - reach, 0), min(extent.bottom + reach, view.shape[0] - 1)
    c0, c1 = max(extent.left - reach, 0), min(extent.right + reach, view.shape[1] - 1)
    sl = (slice(r0, r1 + 1), slice(c0, c1 + 1))
    offset, tolerance = view.smooth_m[sl] - front_surface(view, extent, *sl), view.tolerance_m[sl]
    inner = int(np.ceil(POCKET_INSET_M / view.res_m))
    inside = np.zeros(offset.shape, bool)
    inside[extent.top - r0 + inner:extent.bottom - r0 + 1 - inner,
           extent.left - c0 + inner:extent.right - c0 + 1 - inner] = True
    with np.errstate(invalid="ignore"):
        out = (offset > tolerance) & (offset <= MAX_STANDOFF_M)
        pocket = _pull_sized(inside & (offset < -tolerance) & (offset >= -MAX_POCKET_M), view.res_m)
    other = view.no_depth[sl] & (colour_distance(view.lab[sl], front_colour(view, extent)) > COLOUR_DELTA_E)  # a
    # hole of another colour than the front's: a handle the D415 lost (shadows keep their depth on the plane)
    inner_edge = inside & ~cv2.erode(inside.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    plinth_cells, middle = PLINTH_SHARE * (extent.right - extent.left + 1 - 2 * inner), (extent.top + extent.bottom) / 2
    band = int(round(EDGE_BAND_M / view.res_m))
    candidate = _without_structure((out | pocket | other) & view.seen[sl], view.seen[sl],
                                   (extent.left - c0 - band, extent.right - c0 + band))
    join = max(int(round(JOIN_M / view.res_m)), 1)
    joined = cv2.morphologyEx(candidate.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((join, join), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(joined, connectivity=8)
    with np.errstate(invalid="ignore"):
        surface = view.seen[sl] & (np.abs(offset) <= tolerance)  # on the front's surface
    measured = view.seen[sl] & ~view.no_depth[sl]
    open_past = view.behind[sl] & ~_within(offset.shape, (extent.top - r0, extent.bottom - r0),
                                           (extent.left - c0, extent.right - c0))  # the room seen past the front's
    # edges: an edge pull's tab or a bar on a stile by a door's edge, measured standing out, stands before it and is
    # no less the front's; a line there not measured out of the plane (a shadow, what lies beyond) is judged by its
    # whole ring
    ring_kernel = np.ones((2 * join + 1, 2 * join + 1), np.uint8)
    smallest = MIN_SIZE_M / view.res_m

    def blob_of(member: np.ndarray, box: tuple[slice, slice]) -> Blob | None:
        rows, cols = np.nonzero(member & candidate[box])
        ring = cv2.dilate(member.astype(np.uint8), ring_kernel).astype(bool) & ~member & measured[box]
        rims = [float(np.count_nonzero(r & surface[box])) / np.count_nonzero(r) if r.any() else 0.0
                for r in (ring, ring & ~open_past[box])]
        blob = _blob(view, rows + r0 + box[0].start, cols + c0 + box[1].start, extent, camera_to_base, K, rims[1])
        return replace(blob, rim=rims[0]) if blob is not None and blob.relief_m <= 0 else blob

    blobs = []
    for label in range(1, count):
        x, y, bw, bh, _ = stats[label]
        if max(bw, bh) < smallest:
            continue
        box = (slice(max(y - join, 0), y + bh + join), slice(max(x - join, 0), x + bw + join))
        member = labels[box] == label
        sunk = member & pocket[box]
        if sunk.sum() > (member & out[box]).sum() and (sunk & inner_edge[box]).any() and bw >= plinth_cells \
                and y + bh / 2 + r0 > middle:  # a recess across the front's whole lower edge, on to its sides: the
            continue  # plinth set back under it, not a pull cut into the panel
        parts = side_by_side(member, view.res_m)
        found = [blob_of(part, box) for part in parts]
        if len(parts) == 2 and any(b is None or b.seen_in_colour_only for b in found):  # both measured in depth:
            parts, found = [member], [blob_of(member, box)]  # a lost bar's colour outline steps with its shadows
        if len(parts) == 1 and found[0] is None:  # too large for a handle: taken apart where it crosses the
            # front's sides (a handle joined to what lies beside the front, such as the IR shadow along a side edge),
            # each side's cells into their connected pieces (handles joined only through what lies past a side)
            col = np.arange(box[1].start, box[1].start + member.shape[1])[None, :] + c0
            parts = [member & side for side in (col < extent.left, (col >= extent.left) & (col <= extent.right),
                                                col > extent.right)]
            found = [blob_of(piece, box) for part in parts if part.any() and part.sum() < member.sum()
                     for piece in _pieces(part & candidate[box], join)]
        pieces = _band_past_edge(member, out[box], box[0].start + r0, extent) if len(parts) == 1 else None
        if pieces is not None:
            found = [blob_of(piece, box) for piece in pieces]
        blobs += [b for b in found if b is not None and not _edge_line(view, b, extent)
                  and not _edge_of_beside(view, b, extent)]
    blobs = _under_hidden_edges(view, extent, blobs, camera_to_base, K)
    return _joined_pieces(view, blobs, extent, camera_to_base, K)


def _band_past_edge(member: np.ndarray, out: np.ndarray, row0: int, extent: Extent) -> list[np.ndarray] | None:
    """A candidate (`member`, its grid's first row `row0` of the view; `out`: its cells measured standing out) taken
    apart when its cells without depth past the rectangle's top or bottom edge run along STRUCTURE_SHARE of that
    edge: the dark band under or over a front's whole edge (the shadow there, the gap to what lies beyond) is no part
    of the handles on the edge it joins (an edge pull's tab, however dark, is shorter than its front). The pieces:
    each piece of the rest (a handle each) and the band; None when it is not taken apart."""
    rows = np.arange(member.shape[0])[:, None] + row0
    band = member & ~out & ((rows < extent.top) | (rows > extent.bottom))
    rest = member & ~band
    along = np.count_nonzero(band.any(axis=0))
    if not (rest & out).any() or along < STRUCTURE_SHARE * (extent.right - extent.left + 1):
        return None
    return _pieces(rest) + [band]


def _pieces(cells: np.ndarray, join: int = 1) -> list[np.ndarray]:
    """The connected pieces (8-connected) of a grid of cells, those closer than `join` cells made one."""
    closed = cv2.morphologyEx(cells.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((join, join), np.uint8))
    count, labels = cv2.connectedComponents(closed, connectivity=8)
    return [labels == label for label in range(1, count)]


def _pull_sized(sunk: np.ndarray, res_m: float) -> np.ndarray:
    """`sunk` without its pieces wider than a pull's pocket both ways (MAX_ACROSS_M): a panel set back into its
    frame, which must not join the handle on the frame beside it into one candidate too large for a handle."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(sunk.astype(np.uint8), connectivity=8)
    wide = np.flatnonzero(np.minimum(stats[:, 2], stats[:, 3]) * res_m > MAX_ACROSS_M)
    return sunk & ~np.isin(labels, wide[wide > 0])


def side_by_side(member: np.ndarray, res_m: float) -> list[np.ndarray]:
    """`member` (a candidate's cells, a grid) as one handle, or cut in two where both its edges along its length (the
    grid's longer side) step the same way by at least STEP_M and two cells: two handles side by side that touch in the
    view, one higher than the other (the higher one's top edge steps where it ends, the lower one's bottom edge where
    it starts, at or before that). Each edge steps where the medians over STEP_WINDOW_M either side differ most, by
    as much as the medians of its whole stretches either side differ (but for STEP_WINDOW_M at each end: a handle's
    end is rounded and seen at a slant): a post or a bump in one edge moves neither level. The cut goes midway
    between the two steps (where the handles overlap, the two edges are different handles'); each part keeps at
    least two windows of length."""
    grid = member if member.shape[1] >= member.shape[0] else member.T
    used = np.flatnonzero(grid.any(axis=0))
    window = max(int(np.ceil(STEP_WINDOW_M / res_m)), 2)
    if len(used) < 4 * window:
        return [member]
    index = np.arange(grid.shape[0])[:, None]
    edges = (np.where(grid, index, grid.shape[0]).min(axis=0)[used], np.where(grid, index, -1).max(axis=0)[used])
    at = np.arange(2 * window, len(used) - 2 * window + 1)
    steps = []
    for edge in edges:  # where it steps most over a window either side; by how much its levels either side differ
        local = np.array([np.median(edge[k:k + window]) - np.median(edge[k - window:k]) for k in at])
        k = int(at[np.argmax(np.abs(local))])
        level = np.median(edge[k:-window]) - np.median(edge[window:k])
        steps.append((level if level * local[k - at[0]] > 0 else 0.0, k))
    (top, k_top), (bottom, k_bottom) = steps
    if top * bottom <= 0 or min(abs(top), abs(bottom)) < max(STEP_M / res_m, 2.0) or \
            np.sign(top) * (k_top - k_bottom) < -window:  # the higher handle's top edge ends (or starts) where
        return [member]  # the lower one's bottom edge starts (ends) or past it: they meet or overlap
    cut = used[(k_top + k_bottom) // 2]
    parts = [grid.copy(), grid.copy()]
    parts[0][:, cut:] = False
    parts[1][:, :cut] = False
    return parts if grid is member else [part.T for part in parts]


def _under_hidden_edges(view: PlaneView, extent: Extent, blobs: list[Blob], camera_to_base: np.ndarray,
                        K: np.ndarray) -> list[Blob]:
    """`blobs` with each firm pocket grown by the sunk cells joined to it up to the sides of the front that something
    standing in front of it hides (`_hidden_sides`: a counter's overhang over a top drawer): a pull's pocket cut near
    such an edge runs on under what hides it, and is seen right up to it, not POCKET_INSET_M short of it; its rim is
    the panel around it but for that side."""
    inner = int(np.ceil(POCKET_INSET_M / view.res_m))
    hidden = _hidden_sides(view, extent, inner)
    if not hidden:
        return blobs
    inset = {side: 0 if side in hidden else inner for side in ("top", "bottom", "left", "right")}
    rectangle = np.zeros(view.shape, bool)
    rectangle[extent.top + inset["top"]:extent.bottom + 1 - inset["bottom"],
              extent.left + inset["left"]:extent.right + 1 - inset["right"]] = True
    with np.errstate(invalid="ignore"):
        sunk = rectangle & view.seen & (view.smooth_m < -view.tolerance_m) & (view.smooth_m >= -MAX_POCKET_M)
    _, labels = cv2.connectedComponents(sunk.astype(np.uint8), connectivity=8)
    past = np.zeros(view.shape, bool)
    past[:extent.top] |= "top" in hidden
    past[extent.bottom + 1:] |= "bottom" in hidden
    past[:, :extent.left] |= "left" in hidden
    past[:, extent.right + 1:] |= "right" in hidden
    join = max(int(round(JOIN_M / view.res_m)), 1)
    out = []
    for blob in blobs:
        ids = np.unique(labels[blob.rows, blob.cols])
        grown = np.isin(labels, ids[ids > 0])
        grown[blob.rows, blob.cols] = True
        if not (blob.firm and blob.relief_m < 0) or np.count_nonzero(grown) == len(blob.rows):
            out.append(blob)
            continue
        ring = cv2.dilate(grown.astype(np.uint8), np.ones((2 * join + 1, 2 * join + 1), np.uint8)).astype(bool) \
            & ~grown & view.seen & ~view.no_depth & ~past
        rim = float(np.count_nonzero(ring & view.on_plane)) / max(np.count_nonzero(ring), 1)
        rows, cols = np.nonzero(grown)
        whole = _blob(view, rows, cols, extent, camera_to_base, K, rim)
        out.append(whole if whole is not None and whole.firm else blob)
    return out


def _edge_line(view: PlaneView, blob: Blob, extent: Extent) -> bool:
    """Whether a candidate seen in colour only is a line along one of the rectangle's sides, its middle within
    EDGE_BAND_M of it: the dark line of the gap there or the front's edge seen at a slant (a thin dark bar that the
    D415 loses stands off its front's edges; one on the very edge stands out, and is measured). A side that ends at
    a frame's edge ("frame": where the depth falls past the frame's strip, panel_frame.py) has its gap past it: a line
    inside the rectangle there lies on the strip (a bar on a stile)."""
    if not blob.seen_in_colour_only or blob.elongation < BAR_ELONGATION:
        return False
    band = EDGE_BAND_M / view.res_m
    if abs(blob.axis[0]) >= abs(blob.axis[1]):
        at, sides = float(view.row(blob.centre[1])), {"top": (extent.top, -1), "bottom": (extent.bottom, 1)}
    else:
        at, sides = float(view.col(blob.centre[0])), {"left": (extent.left, -1), "right": (extent.right, 1)}
    return any(abs(at - line) <= band and (extent.ended.get(side) != "frame" or (at - line) * outward > 0)
               for side, (line, outward) in sides.items())


def _edge_of_beside(view: PlaneView, blob: Blob, extent: Extent) -> bool:
    """Whether a candidate measured out of the plane, its cells or its points (no parallax) within EDGE_BAND_M of a
    left or right side where the front's surface stopped (not at a gap, not at the view's border), is the edge of what
    stands beside the front there: the surface just past that side (past the candidate's cells where they run over
    it: a bar overhanging the door's very edge covers the band) stands out of the plane as far as the candidate,
    within the margin a handle stands out by (the smoothed depth blends the two across the edge), or, past a strip
    sunk into the plane, stands out of the plane by that margin (the trough between the front and a unit or wall
    standing out beside it). A handle stands out of what is beside it too (a bar on a door's very edge has the room
    past it, farther back); a pull's pocket cut along an edge has the carcass or the next front past it, no farther
    out than the front. A bar lying across the side (a door's long horizontal bar ending near it) is not such an
    edge, which runs along the side."""
    if blob.seen_in_colour_only or (blob.elongation >= BAR_ELONGATION and abs(blob.axis[0]) > abs(blob.axis[1])):
        return False  # a bar lying across the side, ending near it, is no edge running along it
    band = int(np.ceil(EDGE_BAND_M / view.res_m))
    rows = slice(int(blob.rows.min()), int(blob.rows.max()) + 1)
    cols = np.concatenate([blob.cols, view.col(blob.points[:, 0])])  # where it is seen, and where it is
    margin = max(MIN_RELIEF_M, RELIEF_NOISE * blob.noise_m)
    lo, hi = int(blob.cols.min()), int(blob.cols.max())  # cells running over a side cover the band past it
    left, right = lo if lo < extent.left <= hi else extent.left, hi if lo <= extent.right < hi else extent.right
    for side, short, past in (("left", cols.min() - extent.left, slice(max(left - band, 0), left)),
                              ("right", extent.right - cols.max(), slice(right + 1, right + 1 + band))):
        if extent.ended.get(side) != "surface" or short > band:
            continue
        beside = view.smooth_m[rows, past][view.seen[rows, past]]
        beside = beside[~np.isnan(beside)]
        out = float(np.median(beside)) if len(beside) >= MIN_POINTS else -np.inf
        if out >= (blob.relief_m - margin if blob.relief_m > 0 else margin):
            return True
    return False


def _joined_pieces(view: PlaneView, blobs: list[Blob], extent: Extent, camera_to_base: np.ndarray,
                   K: np.ndarray) -> list[Blob]:
    """`blobs` with the pieces of one bar (`_pieces_of_one_bar`), each measured standing out, made one candidate."""
    blobs = list(blobs)
    merged = True
    while merged:
        merged = False
        for i, a in enumerate(blobs):
            for b in blobs[i + 1:]:
                if all(x.firm and x.relief_m > 0 and not x.seen_in_colour_only for x in (a, b)) \
                        and _pieces_of_one_bar(view, a, b):
                    rows, cols = np.concatenate([a.rows, b.rows]), np.concatenate([a.cols, b.cols])
                    whole = _blob(view, rows, cols, extent, camera_to_base, K, min(a.rim, b.rim))
                    if whole is not None:
                        blobs = [x for x in blobs if x is not a and x is not b] + [whole]
                        merged = True
                        break
            if merged:
                break
    return blobs


def _pieces_of_one_bar(view: PlaneView, a: Blob, b: Blob) -> bool:
    """Whether two candidates are pieces of one bar whose depth the D415 lost between them: both running along the
    same line (horizontal or vertical, each within the other's width of it), one after the other along it, with no
    depth across that line in most of the stretch between their facing ends (between two fronts' handles the fronts'
    surface is measured all across it, but for their gap)."""
    horizontal = [abs(x.axis[0]) >= abs(x.axis[1]) for x in (a, b)]
    along, across = (0, 1) if horizontal[0] else (1, 0)
    if horizontal[0] != horizontal[1] or abs(a.centre[across] - b.centre[across]) > max(a.across_m, b.across_m):
        return False
    first, second = sorted((a, b), key=lambda x: x.centre[along])
    lo, hi = bounds(first, view)[2 * along + 1], bounds(second, view)[2 * along]
    if hi <= lo:
        return False  # side by side along the line: two things, not the pieces of one
    if horizontal[0]:  # the cells of both across the line, the columns between them
        band = slice(int(min(first.rows.min(), second.rows.min())), int(max(first.rows.max(), second.rows.max())) + 1)
        lost = view.no_depth[band, int(view.col(lo)) + 1:int(view.col(hi))].any(axis=0)
    else:
        band = slice(int(min(first.cols.min(), second.cols.min())), int(max(first.cols.max(), second.cols.max())) + 1)
        lost = view.no_depth[int(view.row(hi)) + 1:int(view.row(lo)), band].any(axis=1)
    return lost.size > 0 and float(lost.mean()) >= 0.5


def _blob(view: PlaneView, rows: np.ndarray, cols: np.ndarray, extent: Extent, camera_to_base: np.ndarray,
          K: np.ndarray, rim: float) -> Blob | None:
    """A candidate's geometry, or None when it is not of a handle's size. A short one standing out (a knob or a cup,
    not BAR_ELONGATION times longer than wide) is where its outermost surface is, when that is a knob's head (at most
    KNOB_MAX_M): the pixels on its rim mix its depth with the front's behind it and lie along the lines of sight
    between them, drawing it out toward the camera's side (a bar's length and a tab's are measured along them, and
    its outermost points may lie at one end only; a short bar's outermost surface is a bar)."""
    if len(rows) < 4:
        return None
    with_depth = view.depth_m[rows, cols] > 0
    points = view.points(rows[with_depth], cols[with_depth], camera_to_base, K)
    raw_noise = (view.tolerance_m[rows, cols] - QUANTUM_M) / SMOOTH_NOISE + QUANTUM_M
    points = points[np.abs(points[:, 2]) > raw_noise[with_depth]]  # its own points, not the front's around it
    cells = np.stack([view.s(cols), view.z(rows)], axis=1)
    shape = _extent_of(np.concatenate([points[:, :2], cells[~with_depth]]) if len(points) else cells, view.res_m)
    if len(points) >= MIN_POINTS and np.median(points[:, 2]) > 0 and shape[2] < BAR_ELONGATION * shape[3]:
        outer = points[points[:, 2] >= np.percentile(points[:, 2], 90) - OUTER_LAYER_M, :2]
        if len(outer) >= MIN_POINTS and MIN_SIZE_M <= np.ptp(outer, axis=0).max() + view.res_m <= KNOB_MAX_M:
            shape = _extent_of(outer, view.res_m)
    centre, axis, length, width = shape
    if length < MIN_SIZE_M or length > MAX_LENGTH_M or width > MAX_ACROSS_M:
        return None
    r, c = int(view.row(centre[1])), int(view.col(centre[0]))
    inside = extent.top <= r <= extent.bottom and extent.left <= c <= extent.right
    return Blob(rows, cols, points, centre, axis, length, width, inside, rim, float(np.median(raw_noise)),
                _surface_around(view, rows, cols, extent), float(np.mean(with_depth)))


def _surface_around(view: PlaneView, rows: np.ndarray, cols: np.ndarray, extent: Extent) -> tuple[float, float]:
    """How far (m) the panel a candidate stands on or is sunk into lies off the plane: the quartiles of the offsets
    of the front's measured cells (within `extent`: a carcass or a unit past its sides is no panel) JOIN_M to
    2 JOIN_M around the cells (`rows`, `cols`), past the pixels at the candidate's edges that mix its depth with what
    lies behind ((0, 0) where none is measured). A bowed panel or a window set in shifts the whole ring; a handle's
    own mounts or a neighbouring handle shift part of it, which the quartile nearer the plane leaves out."""
    join = max(int(round(JOIN_M / view.res_m)), 1)
    r0, c0 = max(int(rows.min()) - 2 * join, 0), max(int(cols.min()) - 2 * join, 0)
    box = (slice(r0, int(rows.max()) + 2 * join + 1), slice(c0, int(cols.max()) + 2 * join + 1))
    member = np.zeros(view.offset_m[box].shape, np.uint8)
    member[rows - r0, cols - c0] = 1
    near, far = (cv2.dilate(member, np.ones((2 * k * join + 1, 2 * k * join + 1), np.uint8)).astype(bool)
                 for k in (1, 2))
    grid_r, grid_c = np.indices(member.shape)
    grid_r, grid_c = grid_r + r0, grid_c + c0
    on_front = (grid_r >= extent.top) & (grid_r <= extent.bottom) & (grid_c >= extent.left) & (grid_c <= extent.right)
    offsets = view.offset_m[box][far & ~near & view.seen[box] & on_front]
    offsets = offsets[~np.isnan(offsets)]
    return tuple(float(q) for q in np.percentile(offsets, (25, 75))) if len(offsets) else (0.0, 0.0)


def _extent_of(where: np.ndarray, res_m: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(centre, axis, length, width) of plane positions (s, z): the axis of their largest spread, the middle and the
    length of their 2-98 % range along it, and that range's width across it (each plus a cell)."""
    centred = where - where.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axis = vt[0] if len(vt) else np.array([1.0, 0.0])
    along, across = centred @ axis, centred @ np.array([-axis[1], axis[0]])
    lo, hi = np.percentile(along, [2, 98])
    width = float(np.subtract(*np.percentile(across, [98, 2]))) + res_m
    return where.mean(axis=0) + axis * (lo + hi) / 2, axis, float(hi - lo) + res_m, width


def _hidden_sides(view: PlaneView, extent: Extent, lines: int) -> set[str]:
    """The sides of the front whose `lines` lines just past it stand out of its plane (their median offset beyond the
    noise): something in front of the front hides its edge there."""
    h, w = view.shape
    rows, cols = slice(extent.top, extent.bottom + 1), slice(extent.left, extent.right + 1)
    bands = {"top": (slice(max(extent.top - lines, 0), extent.top), cols),
             "bottom": (slice(extent.bottom + 1, min(extent.bottom + 1 + lines, h)), cols),
             "left": (rows, slice(max(extent.left - lines, 0), extent.left)),
             "right": (rows, slice(extent.right + 1, min(extent.right + 1 + lines, w)))}
    hidden = set()
    for side, band in bands.items():
        seen = view.seen[band] & ~np.isnan(view.smooth_m[band])
        if np.count_nonzero(seen) >= MIN_POINTS and \
                np.median(view.smooth_m[band][seen]) > np.median(view.tolerance_m[band][seen]):
            hidden.add(side)
    return hidden


def _within(shape: tuple[int, int], rows: tuple[int, int], cols: tuple[int, int]) -> np.ndarray:
    """A grid of `shape`, True in the rectangle of `rows` and `cols` (first and last, inclusive)."""
    r, c = np.arange(shape[0])[:, None], np.arange(shape[1])[None, :]
    return (r >= rows[0]) & (r <= rows[1]) & (c >= cols[0]) & (c <= cols[1])


def enclosed_pockets(view: PlaneView) -> np.ndarray:
    """The view's cells sunk into its plane (at most MAX_POCKET_M) in pockets of a pull's size (at most MAX_ACROSS_M
    across, MAX_LENGTH_M along: pulls run horizontal or vertical) with the plane's surface on at least RIM_SHARE of
    the measured ring around them: pockets cut into a panel, not a plinth's recess or a front set back."""
    with np.errstate(invalid="ignore"):
        sunk = view.seen & (view.smooth_m < -view.tolerance_m) & (view.smooth_m >= -MAX_POCKET_M)
    join = max(int(round(JOIN_M / view.res_m)), 1)
    joined = cv2.morphologyEx(sunk.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((join, join), np.uint8))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(joined, connectivity=8)
    measured = view.seen & ~view.no_depth
    ring_kernel = np.ones((2 * join + 1, 2 * join + 1), np.uint8)
    pockets = np.zeros(view.shape, bool)
    for label in range(1, count):
        x, y, bw, bh, _ = stats[label]
        if max(bw, bh) * view.res_m < MIN_SIZE_M or min(bw, bh) * view.res_m > MAX_ACROSS_M \
                or max(bw, bh) * view.res_m > MAX_LENGTH_M:
            continue
        box = (slice(max(y - join, 0), y + bh + join), slice(max(x - join, 0), x + bw + join))
        member = labels[box] == label
        ring = cv2.dilate(member.astype(np.uint8), ring_kernel).astype(bool) & ~member & measured[box]
        if ring.any() and np.count_nonzero(ring & view.on_plane[box]) >= RIM_SHARE * np.count_nonzero(ring):
            pockets[box] |= member
    return pockets


def segment_distance(blob: Blob, point: np.ndarray) -> float:
    """Distance (m) in the plane from `point` (s, z) to the blob's middle line (its length along its axis)."""
    d = np.asarray(point, float) - blob.centre
    t = float(np.clip(d @ blob.axis, -blob.length_m / 2, blob.length_m / 2))
    return float(np.linalg.norm(d - t * blob.axis))


def span_m(view: PlaneView, extent: Extent, axis: np.ndarray) -> float:
    """The rectangle's size (m) along a direction (s, z) in the plane."""
    width, height = (extent.right - extent.left + 1) * view.res_m, (extent.bottom - extent.top + 1) * view.res_m
    return float(abs(axis[0]) * width + abs(axis[1]) * height)


def bounds(blob: Blob, view: PlaneView) -> tuple[float, float, float, float]:
    """(s_min, s_max, z_min, z_max) of the blob's cells."""
    s, z = view.s(blob.cols), view.z(blob.rows)
    return float(s.min()), float(s.max()), float(z.min()), float(z.max())


def _without_structure(candidate: np.ndarray, seen: np.ndarray, ends: tuple[int, int]) -> np.ndarray:
    """`candidate` without the columns where it spans STRUCTURE_SHARE of the seen cells, and the rows where it does
    and runs on past the front's ends (`ends`: its left and right cells, widened by EDGE_BAND_M) along at least half
    the seen cells there: a counter's edge, the floor, a unit's side. A bar across a whole drawer's front stops at
    its ends."""
    out = candidate.copy()
    columns = np.sum(candidate, axis=0) >= STRUCTURE_SHARE * np.maximum(np.sum(seen, axis=0), 1)
    rows = np.sum(candidate, axis=1) >= STRUCTURE_SHARE * np.maximum(np.sum(seen, axis=1), 1)
    past = np.ones(candidate.shape[1], bool)
    past[max(ends[0], 0):max(ends[1], -1) + 1] = False
    seen_past = np.sum(seen[:, past], axis=1)
    rows &= (seen_past == 0) | (np.sum(candidate[:, past], axis=1) >= 0.5 * seen_past)
    out[rows] = False
    out[:, columns] = False
    return out
