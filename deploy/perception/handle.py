"""The handle of the pointed front: which candidate it is, its grip, its style and how well a parallel gripper holds
it.

Grip frame (base frame): `centre` where the fingers close, `bar` along the handle, `close` the direction the fingers
close along (across the handle, in the front's plane), `normal` out of the front. Styles: "bar" (bars of any length),
"knob", "pull" (edge pulls, recessed pulls, cup handles: what fingers hook or pinch rather than wrap), "none".
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from deploy.perception.front_extent import Extent
from deploy.perception.handle_blobs import (
    BAR_ELONGATION,
    EDGE_BAND_M,
    KNOB_MAX_M,
    OUTER_LAYER_M,
    Blob,
    segment_distance,
    span_m,
)
from deploy.perception.plane_view import PlaneView

SNAP_DEG = 20.0  # handles run horizontal or vertical: an axis within this of either is taken as it
COLOUR_ONLY_RELIEF_M = 0.03  # a handle without depth is taken to stand this far out: the middle of real bar and knob
# handles' 25-40 mm
POCKET_LIP_M = 0.01  # a recessed pull is held at its lip, this far inside the pocket's mouth
HIDDEN_REACH_M = 0.02  # the arm's pixels this close beyond a handle's end may hide more of it
FINGER_REACH_M = 0.01  # the fingertips must pass this far behind the grip centre to hold it (half a pad)
FINGER_SPAN_M = 0.025  # two fingertips across a handle add this to its thickness (their own thickness, a margin)
MIN_POCKET_OPENING_M = 0.025  # in a pocket the fingers open at least this: a pull's bar or lip (about 1 cm) and the
# grip's error either side


@dataclass(frozen=True)
class GripperSize:
    """What a parallel gripper can close on: its largest opening (m)."""

    max_opening_m: float = 0.08


@dataclass(frozen=True)
class Handle:
    """The front's handle (see the module docstring). `kind`: "bar", "knob", "edge pull", "recessed pull", "cup" or
    "none"; `length_m` along it, `thickness_m` across it (what the fingers close on), `relief_m` how far its grip
    centre stands out of the front (negative: in a pocket), `clearance_m` the room behind the grip centre for the
    fingertips; `graspability` in 0-1 (0: the gripper cannot hold it), `hidden` the share of it the arm hides,
    `reason` one line on how it should be held or why it cannot; `open_m` how wide the fingers open to approach it
    (the gripper's opening; inside a recessed pull's pocket, what the pocket leaves them)."""

    style: str
    kind: str
    centre: np.ndarray
    bar: np.ndarray
    close: np.ndarray
    normal: np.ndarray
    length_m: float
    thickness_m: float
    relief_m: float
    clearance_m: float
    graspability: float
    hidden: float
    reason: str
    open_m: float


def own_blob(blobs: list[Blob], view: PlaneView, extent: Extent) -> Blob | None:
    """The front's handle among the candidates: a firm one whose centre lies on the front (its rectangle `extent`,
    inclusive), else just beyond its top or bottom edge (an edge pull's tab), else just beyond a side where the
    front's surface stopped (`on_surface_side`); and not running past both the front's ends along it (by more
    than an edge band each), unless the view cuts the front that way (such a line is an edge or its shadow). Among
    several: an edge pull on the top edge (where a hand reaches for it on a drawer or a base door; the tab on the
    bottom edge is then the next front's), else the one nearest the user's pixel (the view's origin)."""
    rows, cols = (extent.top, extent.bottom), (extent.left, extent.right)
    band = EDGE_BAND_M / view.res_m
    on, near, beside = [], [], []
    for b in blobs:
        r, c = float(view.row(b.centre[1])), float(view.col(b.centre[0]))
        if not b.firm or rows_apart(b, extent) > band or _longer_than(b, view, extent):
            continue
        if not cols[0] <= c <= cols[1]:
            if on_surface_side(b, view, extent):
                beside.append(b)
        elif rows[0] <= r <= rows[1]:
            on.append(b)
        else:
            near.append(b)
    found = on or near or beside
    if not found:
        return None
    on_top = [b for b in found if _kind(b, view, rows) == "edge pull" and
              abs(b.centre[1] - view.z(rows[0])) <= EDGE_BAND_M]
    return min(on_top or found, key=lambda b: segment_distance(b, np.zeros(2)))


def on_surface_side(blob: Blob, view: PlaneView, extent: Extent) -> bool:
    """Whether a candidate's centre lies beyond the rectangle `extent`'s left or right side, between its top and
    bottom, where the front's surface stopped rather than at a gap, within EDGE_BAND_M of that side: a handle on a
    door's very edge (the surface past it is too narrow to be crossed). A bar running along the side, as
    refrigerators and wardrobes have, may overhang the edge by up to its width: its cells, not its centre, lie within
    the band. A bar across the side is a neighbour's whose end comes near it."""
    c, r = float(view.col(blob.centre[0])), float(view.row(blob.centre[1]))
    if extent.left <= c <= extent.right or not extent.top <= r <= extent.bottom:
        return False
    side = "left" if c < extent.left else "right"
    along = abs(_snapped(blob.axis)[1]) == 1.0
    cells = (blob.cols.max(), blob.cols.min()) if along else (c, c)
    apart = max(extent.left - float(cells[0]), float(cells[1]) - extent.right, 0.0)
    return extent.ended.get(side) == "surface" and apart <= EDGE_BAND_M / view.res_m


def spills_over_edge(blob: Blob, view: PlaneView, extent: Extent) -> bool:
    """Whether a candidate stands beyond the rectangle `extent`'s top or bottom edge, farther than an edge pull's
    tab (EDGE_BAND_M), with its cells on that edge: a bar along the edge seen from above or below."""
    band = EDGE_BAND_M / view.res_m
    r = float(view.row(blob.centre[1]))
    return extent.left <= view.col(blob.centre[0]) <= extent.right and rows_apart(blob, extent) <= band and \
        not extent.top - band <= r <= extent.bottom + band


def tab_over_top(blob: Blob, view: PlaneView, extent: Extent) -> bool:
    """Whether a candidate measured standing out of the plane has its centre just over the rectangle `extent`'s top
    edge (within EDGE_BAND_M), between its sides: the tab or bar along the top edge that `own_blob` takes for the
    front's own handle (the gap's dark line there, seen in colour only, is none)."""
    z, top = float(blob.centre[1]), float(view.z(extent.top))
    return blob.relief_m > 0 and not blob.seen_in_colour_only and \
        extent.left <= view.col(blob.centre[0]) <= extent.right and top < z <= top + EDGE_BAND_M


def rows_apart(blob: Blob, extent: Extent) -> int:
    """The rows of the view between the candidate's cells and the rectangle's (0 where they meet). A bar seen from
    above covers the front below it in the view (the rays past it meet the plane there), so a bar along a front's top
    edge, whose surface above it is too narrow to resume, ends the rectangle at its cells, not at its centre."""
    return max(extent.top - int(blob.rows.max()), int(blob.rows.min()) - extent.bottom, 0)


def describe(blob: Blob, view: PlaneView, rows: tuple[int, int], gripper: GripperSize,
             camera: np.ndarray) -> Handle:
    """The grip of the handle `blob` on the front spanning `rows` of `view`, seen from `camera` (its centre, base
    frame)."""
    plane = view.plane
    axis = _snapped(blob.axis)
    across = np.array([-axis[1], axis[0]])
    points = blob.points
    kind = _kind(blob, view, rows)
    thickness = _thickness(blob, axis, across, view.res_m)
    if kind == "recessed pull":  # its pocket's mouth: where the rays enter the front (the measured points of its
        # walls and back lie beside it, seen obliquely), and the pocket's width across it
        cells = np.stack([view.s(blob.cols), view.z(blob.rows)], axis=1)
        blob = replace(blob, centre=(cells.min(axis=0) + cells.max(axis=0)) / 2)
        thickness = float(np.ptp(cells @ across)) + view.res_m
    outer = float(np.percentile(points[:, 2], 90)) if len(points) else 0.0
    if blob.seen_in_colour_only:  # no depth on it: where its line of sight stands the usual standoff out
        centre = _along_sight(plane.point(blob.centre[0], blob.centre[1]), camera, plane, COLOUR_ONLY_RELIEF_M)
        blob = replace(blob, centre=plane.coordinates(centre[None])[0, :2])
        relief = clearance = COLOUR_ONLY_RELIEF_M
    elif kind == "edge pull":  # a tab out of the edge: the grip halfway out
        relief = outer / 2
    elif kind == "recessed pull":  # its lip, just inside the pocket's mouth; the fingertips have room down to the
        # pocket's back, its deepest points
        back = float(np.percentile(points[:, 2], 10)) if len(points) else outer
        relief, clearance = -POCKET_LIP_M, -back - POCKET_LIP_M
    elif kind == "cup":  # the fingers close across the shell's height, on its outer plate (a plate's thickness)
        relief = outer - OUTER_LAYER_M / 2
    else:  # the fingers close around its middle, half its thickness behind its front surface
        relief = outer - thickness / 2
    if kind not in ("recessed pull",) and not blob.seen_in_colour_only:
        clearance = relief
    bar = axis[0] * plane.right + axis[1] * plane.up
    close = across[0] * plane.right + across[1] * plane.up
    centre = plane.point(blob.centre[0], blob.centre[1], relief)
    hidden = _hidden_share(blob, view, axis)
    score, reason = _graspability(kind, thickness, clearance, hidden, gripper)
    style = {"bar": "bar", "knob": "knob"}.get(kind, "pull")
    opening = gripper.max_opening_m if kind != "recessed pull" else \
        min(max((thickness - FINGER_SPAN_M) / 2, MIN_POCKET_OPENING_M), gripper.max_opening_m)
    # in a pocket the fingers open to half the room their own thickness leaves (the other half keeps their outer faces
    # off its walls: the grip's error, the approach's tilt), but wide enough around its bar for the grip's error
    return Handle(style, kind, centre, bar, close, plane.normal.copy(), blob.length_m, thickness, relief, clearance,
                  score, hidden, reason, opening)


def _along_sight(on_plane: np.ndarray, camera: np.ndarray, plane, offset: float) -> np.ndarray:
    """The point of the line of sight from `camera` to `on_plane` (a point of `plane`) that stands `offset` out of
    the plane."""
    ray = on_plane - camera
    return on_plane - ray * offset / float((camera - on_plane) @ plane.normal)


def _snapped(axis: np.ndarray) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.degrees(np.arctan2(abs(a[1]), abs(a[0])))
    if angle <= SNAP_DEG:
        return np.array([1.0, 0.0])
    if angle >= 90.0 - SNAP_DEG:
        return np.array([0.0, 1.0])
    return a if a[0] >= 0 else -a


def _longer_than(blob: Blob, view: PlaneView, extent: Extent) -> bool:
    """Whether the blob runs past both ends of the front along its axis by more than EDGE_BAND_M each, on a front
    whose ends that way are seen (a front found no wider than its own bar has the bar's length, give or take)."""
    sides = ("left", "right") if abs(_snapped(blob.axis)[0]) == 1.0 else ("top", "bottom")
    if any(extent.ended.get(side) == "view" for side in sides):
        return False
    return blob.length_m > span_m(view, extent, _snapped(blob.axis)) + 2 * EDGE_BAND_M


def _kind(blob: Blob, view: PlaneView, rows: tuple[int, int]) -> str:
    if blob.relief_m < 0:
        return "recessed pull"
    top, bottom = view.z(rows[0]), view.z(rows[1])
    near_edge = min(abs(blob.centre[1] - top), abs(blob.centre[1] - bottom)) <= EDGE_BAND_M
    horizontal = abs(_snapped(blob.axis)[0]) == 1.0
    elongation = blob.length_m / max(_thickness(blob, _snapped(blob.axis), np.array([-blob.axis[1], blob.axis[0]]),
                                                view.res_m), 1e-3)
    if near_edge and horizontal and elongation >= BAR_ELONGATION:
        return "edge pull"
    if elongation >= BAR_ELONGATION:
        return "bar"
    if blob.length_m <= KNOB_MAX_M:
        return "knob"
    return "cup"


def _thickness(blob: Blob, axis: np.ndarray, across: np.ndarray, res_m: float) -> float:
    """Across the handle (m): the spread across it of its outermost measured points (within OUTER_LAYER_M of its
    front surface: the bar, not its posts or a pocket's back) in its middle half, else of its cells."""
    points = blob.points
    if len(points) >= 8:
        outer = points[points[:, 2] >= np.percentile(points[:, 2], 90) - OUTER_LAYER_M]
        middle = outer[np.abs((outer[:, :2] - blob.centre) @ axis) <= blob.length_m / 4]
        if len(middle) >= 4:
            spread = np.subtract(*np.percentile(middle[:, :2] @ across, [95, 5]))
            return float(np.clip(spread + res_m, res_m, blob.across_m))
    return float(min(blob.across_m, blob.length_m))


def _hidden_share(blob: Blob, view: PlaneView, axis: np.ndarray) -> float:
    """How much of the handle the arm may hide: half for each end of it that the arm's pixels (unseen cells inside
    the image) meet within HIDDEN_REACH_M along its axis."""
    ends = []
    h, w = view.shape
    cells = np.stack([view.s(blob.cols), view.z(blob.rows)], axis=1)  # where it is seen in the view (with parallax)
    middle = cells.mean(axis=0)
    along = (cells - middle) @ axis
    for sign, end in ((-1.0, along.min()), (1.0, along.max())):
        hidden = False
        for step in np.arange(1, int(np.ceil(HIDDEN_REACH_M / view.res_m)) + 1):
            tip = middle + axis * (end + sign * step * view.res_m)
            r, c = int(view.row(tip[1])), int(view.col(tip[0]))
            inside_image = 0 <= r < h and 0 <= c < w and 0 <= view.map_uv[r, c, 0] and 0 <= view.map_uv[r, c, 1]
            hidden |= inside_image and not view.seen[r, c]
        ends.append(hidden)
    return 0.5 * sum(ends)


def _graspability(kind: str, thickness: float, clearance: float, hidden: float,
                  gripper: GripperSize) -> tuple[float, str]:
    """A 0-1 score and one line: whether the fingers open wide enough around it (a recessed pull's pocket, which
    `thickness` measures: whether it holds two fingers) and reach behind it."""
    width = thickness + FINGER_SPAN_M
    if kind == "recessed pull" and thickness <= FINGER_SPAN_M:
        return 0.0, (f"the recessed pull's pocket is {thickness * 100:.1f} cm across: too narrow for two fingers "
                     f"({FINGER_SPAN_M * 100:.1f} cm)")
    if kind != "recessed pull" and width > gripper.max_opening_m:
        return 0.0, (f"the {kind} is {thickness * 100:.1f} cm thick: two fingers need {width * 100:.1f} cm, more than "
                     f"the gripper's {gripper.max_opening_m * 100:.1f} cm opening")
    reach = min(1.0, max(clearance, 0.0) / FINGER_REACH_M)
    score = reach * (1.0 - 0.5 * hidden)
    how = {"bar": "close the fingers around the bar", "knob": "close the fingers around the knob's head",
           "edge pull": "pinch the tab standing out of the front's edge", "recessed pull": "reach into the pocket "
           "and close the fingers around its bar", "cup": "close the fingers across the cup's shell"}[kind]
    if reach < 1.0:
        how += f" (only {clearance * 100:.1f} cm of room behind its grip for the fingertips)"
    return score, how
