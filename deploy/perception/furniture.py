"""The piece of furniture a pointed front belongs to: its static surfaces, as the static reference of the moving
part, the paper's box baseline, the grasp's collision checks and reports.

A unit's fronts stack in a column (drawers, a drawer over a door): the furniture is the column of the front's face
above and below it, as far as the face's surface goes (to the counter's overhang or the unit's top, to its plinth),
with what stands out of it (handles) or sinks into it (pockets), and, within that column's width, the carcass around
it: the plinth, the rail above the fronts, a free-standing unit's top. The floor, the counter (its overhang stands in
front of the face), the wall, what stands on or before the unit, and the units beside the column stay out. Units
side by side whose gaps the camera does not see (a pair of doors) are not told apart: the column is the pointed
front's width.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from deploy.perception.front import Front, plane_coordinates
from deploy.perception.front_extent import Extent, surface_walk
from deploy.perception.handle_blobs import MAX_POCKET_M, MAX_STANDOFF_M

UNIT_DEPTH_M = 0.9  # furniture reaches at most this far behind its fronts (base units 0.6 m, free-standing 0.8 m)
SIDE_PANEL_M = 0.025  # a carcass side stands this far beside its fronts (a panel's thickness and a reveal)
TOP_PANEL_M = 0.05  # a unit's top (a rail, a top panel) rises at most this far above its fronts
FLOOR_LAYER_M = 0.02  # the floor's points lie within this of its height (the D415's noise at 1.5 m, a rug)


@dataclass(frozen=True)
class Furniture:
    """The furniture's pixels (`mask`, (H, W), the arm's left out) and its face in the front's plane (s, z ranges,
    m): `ended` says what bounds it on each side ("surface", "view"; left and right are the front's)."""

    mask: np.ndarray
    s_range: tuple[float, float]
    z_range: tuple[float, float]
    ended: dict[str, str]


def find_furniture(front: Front, depth_m: np.ndarray, K: np.ndarray, T_base_camera: np.ndarray,
                   robot: np.ndarray) -> Furniture:
    """The furniture of `front` in the frame it was found in (its depth, intrinsics and calibrated pose)."""
    view, e = front.view, front.extent
    (top, ended_top), (bottom, ended_bottom) = surface_walk(view, Extent(e.top, e.bottom, e.left, e.right, {}))
    s0, s1 = view.s(e.left - 0.5), view.s(e.right + 0.5)
    z_top, z_bottom = float(view.z(top - 0.5)), float(view.z(bottom + 0.5))
    s, z, offset = plane_coordinates(front.view.plane, depth_m, K, T_base_camera)
    seen = (depth_m > 0) & ~robot
    column = seen & (s >= s0 - SIDE_PANEL_M) & (s <= s1 + SIDE_PANEL_M)
    face = column & (offset >= -MAX_POCKET_M) & (offset <= MAX_STANDOFF_M) & (z >= z_bottom) & (z <= z_top)
    below = column & (z < z_bottom) & (offset < 0)  # the plinth, recessed under the fronts
    floor = _floor_height(z[column & (z < z_bottom) & (offset > 0)])
    if floor is not None:
        below &= z > floor + FLOOR_LAYER_M
    overhang = np.count_nonzero(column & (z > z_top) & (z <= z_top + TOP_PANEL_M) & (offset > MAX_STANDOFF_M / 4))
    above = column & (z > z_top) & (z <= z_top + TOP_PANEL_M) & (offset <= 0) & (offset >= -UNIT_DEPTH_M)
    if overhang > np.count_nonzero(above):  # a counter overhangs the face: what is above belongs to it
        above[:] = False
    return Furniture(face | below | above, (float(s0), float(s1)), (z_bottom, z_top),
                     {"top": ended_top, "bottom": ended_bottom, "left": front.ended.get("left", "view"),
                      "right": front.ended.get("right", "view")})


def _floor_height(z: np.ndarray) -> float | None:
    """The floor's height (m) from the points below the face and in front of it (the floor before the unit): the
    lowest dense layer; None when there are too few."""
    if len(z) < 50:
        return None
    low = float(np.percentile(z, 5))
    layer = z[np.abs(z - low) <= FLOOR_LAYER_M]
    return float(np.median(layer)) if len(layer) >= 0.3 * len(z) else None
