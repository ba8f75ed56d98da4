"""From the user's pointer to the part to open: one pixel (`--point U V`) or a box (`--box X0 Y0 X1 Y1`) on the
first frame gives the front there (deploy/perception/front.py), its handle (handle.py) and the furniture it belongs
to (furniture.py); or one line (a PointerError) saying what was seen there and what to do.

Everything here is a function of one frame (colour, depth, intrinsics, the calibrated camera pose), the arm's pixels
(the self-filter's mask) and the pointer: no label and no truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from deploy.errors import PartHiddenError, PointerError
from deploy.perception.base import Pointer
from deploy.perception.front import (
    MAX_FRONT_HEIGHT_M,
    MAX_FRONT_WIDTH_M,
    Front,
    box_seed,
    find_front,
    plane_coordinates,
)
from deploy.perception.front_extent import Extent
from deploy.perception.furniture import Furniture, find_furniture
from deploy.perception.handle import GripperSize, Handle, describe, own_blob
from deploy.perception.handle_blobs import handle_blobs
from deploy.perception.handle_pixel import behind_handle
from deploy.perception.plane_view import PlaneView
from drivers.camera.base import Frame

MIN_FRONT_M = 0.06  # the narrowest real fronts (a spice drawer) are about 10 cm: a face narrower is an edge
WALL_BEHIND_M = 0.15  # furniture stands out of the wall by more than this (wall units 30 cm deep) ...
WALL_SHARE = 0.005  # ... so around a front the camera sees at least this share of the image farther back
SIDE_BAND_M = (0.01, 0.06)  # just past a front's side lie its gap, the carcass's rim or the plinth's recess ...
SIDE_DROP_M = 0.02  # ... this far behind it at least (and beyond the D415's noise), over ...
SIDE_DROP_SHARE = 0.5  # ... this share of what is seen there
MIN_SEEN_SHARE = 0.3  # a front the arm hides more of than this is not seen well enough to grasp


@dataclass(frozen=True)
class PointedPart:
    """The part the user pointed at: its `front`, `handle` and `furniture`; `pixel` the seed pixel used;
    `timings_ms` by step."""

    front: Front
    handle: Handle
    furniture: Furniture
    pixel: tuple[int, int]
    timings_ms: dict[str, float] = field(default_factory=dict)


def point_at(frame: Frame, robot: np.ndarray, pointer: Pointer, reach_m: float | None = None,
             gripper: GripperSize | None = None) -> PointedPart:
    """The front, handle and furniture the user pointed at (see the module docstring). `robot`: the arm's pixels
    (SelfFilter.mask); `reach_m`: the arm's reach from its base, to refuse a handle beyond it. Raises PointerError
    with one line for a pointer off the image, on the arm, on the floor, a counter or a wall, on a front with no
    handle, on a front the arm hides, or on a handle out of reach."""
    clock, timings = time.perf_counter(), {}
    if frame.T_base_camera is None:
        raise PointerError(f"frame {frame.index} has no camera pose: finding the pointed part needs the camera's "
                           "calibration (`deploy calibrate hand-eye`, or --calibration)")
    u, v = seed_pixel(frame, pointer)
    if pointer.box is not None:
        u, v = box_seed(frame, robot, pointer.box)
    if robot[v, u]:
        raise PartHiddenError(f"{pointer}: pixel ({u}, {v}) is on the arm, which hides the part there: move the arm "
                              "out of the view (the episode swings it aside) or point at a part of the front it does "
                              "not hide")
    if pointer.box is None:
        u, v = behind_handle(frame, robot, u, v)
    try:
        front = find_front(frame, robot, u, v, pointer.box)
    except PointerError as e:
        raise PointerError(f"{pointer}: {e}") from None
    timings["front"] = _lap(clock)
    _check_seen(front, pointer, (u, v))
    _check_not_wall(frame, robot, front, pointer, (u, v))
    try:
        handle = find_handle(front, frame, gripper or GripperSize(), pointer)
    except PointerError:
        _check_is_front(front, pointer, (u, v))  # no handle: is it a front at all?
        raise
    timings["handle"] = _lap(clock) - timings["front"]
    if reach_m is not None and np.linalg.norm(handle.centre) > reach_m:
        p = handle.centre
        raise PointerError(f"{pointer}: the {handle.kind} at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m is "
                           f"{np.linalg.norm(p):.2f} m from the arm's base, beyond its {reach_m:.2f} m reach: move "
                           "the robot closer to the furniture, or point at a part within reach")
    furniture = find_furniture(front, frame.depth_m, frame.intrinsics.K, frame.T_base_camera, robot)
    timings["furniture"] = _lap(clock) - sum(timings.values())
    timings["total"] = _lap(clock)
    return PointedPart(front, handle, furniture, (u, v), timings)


def _lap(clock: float) -> float:
    return (time.perf_counter() - clock) * 1e3


def seed_pixel(frame: Frame, pointer: Pointer) -> tuple[int, int]:
    """The pixel the front is looked for from: the pointer's pixel, or its box's centre; PointerError when it lies
    off the image."""
    h, w = frame.depth_m.shape
    if pointer.box is not None:
        x0, y0, x1, y1 = pointer.box
        if not (x1 > x0 and y1 > y0):
            raise PointerError(f"{pointer}: the box is empty: give X0 Y0 X1 Y1 with X1 > X0 and Y1 > Y0, around the "
                               "part's front")
    u, v = pointer.u, pointer.v
    if not (0 <= u < w and 0 <= v < h):
        raise PointerError(f"{pointer}: pixel ({u:g}, {v:g}) is outside the {w}x{h} image: give a pixel on the part's "
                           f"front with 0 <= U < {w} and 0 <= V < {h} (`deploy cameras snapshot` shows the image)")
    return int(u), int(v)


def _check_seen(front: Front, pointer: Pointer, pixel: tuple[int, int]) -> None:
    """PointerError when the arm hides most of the pointed front."""
    e = front.extent
    seen = front.view.seen[e.top:e.bottom + 1, e.left:e.right + 1]
    if seen.mean() < MIN_SEEN_SHARE:
        hidden = 100 * (1 - seen.mean())
        raise PartHiddenError(f"{pointer}: pixel ({pixel[0]}, {pixel[1]}): the arm hides {hidden:.0f} % of the pointed "
                              "front: move the arm out of the view (the episode swings it aside) and look again")


def _check_not_wall(frame: Frame, robot: np.ndarray, front: Front, pointer: Pointer, pixel: tuple[int, int]) -> None:
    """PointerError when nothing in view lies behind the pointed surface's plane: furniture stands out of the room's
    walls (a counter's top, a unit's top, the wall above or beside it lie behind its fronts), a wall does not. A
    surface cut from its neighbours by gaps on two sides, or of a front's size with a side past which the view drops
    behind it (`side_drops_behind`), is a front however close the camera is and whatever hides the room behind."""
    if sum(why == "gap" for why in front.ended.values()) >= 2:
        return
    if front.width_m <= MAX_FRONT_WIDTH_M and front.height_m <= MAX_FRONT_HEIGHT_M and \
            side_drops_behind(front.view, front.extent):
        return
    _, _, offset = plane_coordinates(front.plane, frame.depth_m, frame.intrinsics.K, frame.T_base_camera)
    with np.errstate(invalid="ignore"):
        behind = np.count_nonzero((offset < -WALL_BEHIND_M) & ~robot)
    if behind < WALL_SHARE * np.count_nonzero(frame.depth_m > 0):
        raise PointerError(f"{pointer}: pixel ({pixel[0]}, {pixel[1]}) is on the farthest vertical surface in view "
                           f"({front.width_m:.2f} x {front.height_m:.2f} m, nothing seen behind it): a wall, not a "
                           "front; point at the drawer's or door's front")


def side_drops_behind(view: PlaneView, extent: Extent) -> bool:
    """Whether, just past one of the rectangle's sides (SIDE_BAND_M out), most of what is seen (SIDE_DROP_SHARE, over
    at least half the band) lies behind the plane by SIDE_DROP_M and the D415's noise: a front's side meets its gap,
    the carcass's rim set back or the plinth's recess, while the room's wall is the farthest surface and what lies past
    its sides (furniture, the floor, the next wall) stands in front of it."""
    near, far = (max(int(round(m / view.res_m)), 1) for m in SIDE_BAND_M)
    h, w = view.shape
    e = extent
    rows, cols = slice(e.top, e.bottom + 1), slice(e.left, e.right + 1)
    bands = ((slice(max(e.top - far, 0), max(e.top - near + 1, 0)), cols),
             (slice(min(e.bottom + near, h), min(e.bottom + far + 1, h)), cols),
             (rows, slice(max(e.left - far, 0), max(e.left - near + 1, 0))),
             (rows, slice(min(e.right + near, w), min(e.right + far + 1, w))))
    for band, length in zip(bands, (e.right - e.left + 1,) * 2 + (e.bottom - e.top + 1,) * 2, strict=True):
        seen = view.seen[band]
        n_seen = np.count_nonzero(seen)
        if n_seen < 0.5 * (far - near + 1) * length:
            continue
        with np.errstate(invalid="ignore"):
            behind = view.smooth_m[band] < -np.maximum(view.tolerance_m[band], SIDE_DROP_M)
        if np.count_nonzero(behind & seen) >= SIDE_DROP_SHARE * n_seen:
            return True
    return False


def _check_is_front(front: Front, pointer: Pointer, pixel: tuple[int, int]) -> None:
    """PointerError when the vertical surface at the pixel, with no handle on it, is not a front: wider or taller
    than furniture fronts are, or a narrow band (a counter's edge)."""
    at = f"{pointer}: pixel ({pixel[0]}, {pixel[1]})"
    size = f"{front.width_m:.2f} x {front.height_m:.2f} m"
    if front.width_m > MAX_FRONT_WIDTH_M or front.height_m > MAX_FRONT_HEIGHT_M:
        raise PointerError(f"{at} is on a vertical surface larger than any drawer or door front ({size}): a wall or "
                           "a side panel; point at the drawer's or door's front")
    if min(front.width_m, front.height_m) < MIN_FRONT_M and not front.cut:
        raise PointerError(f"{at} is on a narrow vertical band ({size}): a counter's or a shelf's edge, not a front; "
                           "point at the drawer's or door's front below or above it")


def find_handle(front: Front, frame: Frame, gripper: GripperSize, pointer: Pointer | str = "") -> Handle:
    """The front's handle and its grip; PointerError when the front shows none (one line saying what was seen)."""
    e = front.extent
    blobs = handle_blobs(front.view, e, frame.T_base_camera, frame.intrinsics.K)
    blob = own_blob(blobs, front.view, e)
    if blob is None:
        seen = front.view.seen[e.top:e.bottom + 1, e.left:e.right + 1].mean()
        size = f"{front.width_m:.2f} x {front.height_m:.2f} m"
        said = f"{pointer}: the pointed front ({size}) shows no handle, knob or pull"
        if seen < 0.9:
            raise PartHiddenError(f"{said}; the arm hides {100 * (1 - seen):.0f} % of it: move the arm away and look "
                                  "again")
        raise PointerError(f"{said}: a push-to-open front needs a push first (not supported); point at a front with a "
                           "handle")
    return describe(blob, front.view, (e.top, e.bottom), gripper, np.asarray(frame.T_base_camera)[:3, 3])
