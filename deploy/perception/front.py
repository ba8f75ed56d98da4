"""The front a user pointed at: its plane from the depth around the pixel, its rectangle in the plane (gaps between
fronts, where its surface ends) and its pixels.

Pure functions of one frame (colour, depth, intrinsics, the calibrated camera pose), the arm's pixels (the
self-filter's mask) and the user's pixel. Base frame, metres, z up.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from deploy.errors import PointerError
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.planes import dominant_plane
from deploy.perception.front_cuts import NARROW_FRONT_M, split_by_handles, split_wide
from deploy.perception.front_extent import Extent, front_extent, rows_over_columns
from deploy.perception.handle import own_blob
from deploy.perception.handle_blobs import (
    MAX_POCKET_M,
    Blob,
    enclosed_pockets,
    handle_blobs,
    segment_distance,
)
from deploy.perception.panel_frame import framed_panel
from deploy.perception.plane_view import D415, NOISE_SIGMAS, QUANTUM_M, UP, PlaneFrame, PlaneView, rectify
from deploy.perception.seed_surface import seed_surface
from drivers.camera.base import Frame

SEED_RADII_PX = (12, 24, 48)  # the plane at the pixel is fitted to the depth this close to it (the first with enough)
MIN_SEED_POINTS = 60
FRONT_TILT_DEG = 15.0  # fronts are vertical: the calibration's 0.5 deg and the fit's error stay well inside this
FLAT_TILT_DEG = 45.0  # a surface tilted more than this from vertical faces up or down: floor, counter, shelf
REFINE_RADIUS_M = 0.5  # the plane is refined over the surface this far around the pixel (neighbouring fronts are
# coplanar and help) ...
REFINE_SLOPES_DEG = (5.0, 2.0, 0.5)  # ... keeping points within the noise plus these slopes of their distance
FLOOR_STEP_M = 0.05  # a horizontal surface with things more than this below it is not the floor ...
FLOOR_SHARE = 0.02  # ... when they fill at least this share of the view (more than depth noise and flying pixels)
MAX_FRONT_WIDTH_M = 1.2  # the widest drawer or door fronts of real furniture
MAX_FRONT_HEIGHT_M = 2.4  # the tallest (a tall unit's door)


@dataclass(frozen=True)
class Front:
    """The pointed front. `plane`: its frame, origin at the front's centre, normal out of the front (toward the
    camera), `right` and `up` along its sides; `width_m` x `height_m`; `corners` (4, 3) base frame, as seen facing
    it: top left, top right, bottom right, bottom left; `mask` (H, W) its pixels (not its handle); `ended` what
    ended each side ("gap", "surface", "view": the image's border, the side is cut and the front may be larger);
    `view` and `extent` the rectified view and the rectangle's cells in it (for the handle search). Sides also end at
    "handle" (cut between two handles: the gap was not seen), "box" (the user's box) and "frame" (the edge of the
    frame a panel is set into: panel_frame.py)."""

    plane: PlaneFrame
    width_m: float
    height_m: float
    corners: np.ndarray
    mask: np.ndarray
    ended: dict[str, str]
    view: PlaneView
    extent: Extent

    @property
    def cut(self) -> tuple[str, ...]:
        """The sides whose edge the camera did not see."""
        return tuple(side for side, why in self.ended.items() if why == "view")


def pixel_ray(frame: Frame, u: float, v: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera's centre and the unit direction of the ray through pixel (u, v), base frame."""
    T = np.asarray(frame.T_base_camera, float)
    d = T[:3, :3] @ np.linalg.solve(frame.intrinsics.K, [u, v, 1.0])
    return T[:3, 3].copy(), d / np.linalg.norm(d)


def seed_plane(frame: Frame, robot: np.ndarray, u: int, v: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(point, unit normal, depth at the pixel) of the surface at pixel (u, v): RANSAC over the depth close to it,
    within the D415's noise, in the nearest window (SEED_RADII_PX) with enough depth whose plane stands within
    FRONT_TILT_DEG of vertical, else in the nearest window with enough depth (at a metre and more, the noise over a
    window a few centimetres wide tilts its plane by as much). A window's plane that is not vertical is fitted again
    to the window's piece of surface holding the pixel (`_own_surface`): a plane may join two surfaces a step apart
    (a low front under a counter's edge, seen from above, and that edge). Raises PointerError when there is no depth
    around the pixel."""
    h, w = frame.depth_m.shape
    nearest = None
    for radius in SEED_RADII_PX:
        rows, cols = slice(max(v - radius, 0), v + radius + 1), slice(max(u - radius, 0), u + radius + 1)
        window = np.zeros((h, w), bool)
        window[rows, cols] = True
        window &= ~robot & (frame.depth_m > 0)
        if np.count_nonzero(window) < MIN_SEED_POINTS:
            continue
        points = depth_to_points(frame.depth_m, frame.intrinsics.K, window, frame.T_base_camera)
        depth = float(np.median(frame.depth_m[window]))
        tolerance = NOISE_SIGMAS * float(D415.sigma_m(depth, frame.intrinsics.fx)) + QUANTUM_M / 2
        fit = _plane_fit(points, tolerance) + (depth,)
        if tilt_deg(fit[1]) <= FRONT_TILT_DEG:
            return fit
        crop = np.where(window[rows, cols], frame.depth_m[rows, cols], 0.0)
        own = points[_own_surface(crop, (v - rows.start, u - cols.start), tolerance)[window[rows, cols]]]
        if len(own) >= MIN_SEED_POINTS and tilt_deg((own_fit := _plane_fit(own, tolerance))[1]) <= FRONT_TILT_DEG:
            return own_fit + (depth,)
        nearest = nearest or fit
    if nearest is None:
        raise PointerError(f"pixel ({u}, {v}) has no depth within {SEED_RADII_PX[-1]} px (too close, too far, or a "
                           "dark or shiny surface): point at the front's panel where the depth image shows it")
    return nearest


def _plane_fit(points: np.ndarray, tolerance_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(centre, unit normal) of the points' dominant plane (RANSAC within `tolerance_m`, then least squares)."""
    inside = points[dominant_plane(points, tolerance_m)]
    centre = inside.mean(axis=0)
    return centre, np.linalg.svd(inside - centre, full_matrices=False)[2][2]


def _own_surface(depth_m: np.ndarray, pixel: tuple[int, int], step_m: float) -> np.ndarray:
    """Mask of the pixels of `depth_m` (0: none) on the piece of surface nearest `pixel` (row, col), cut from what
    lies a step in front of or behind it: the pixels whose depth bends by less than `step_m` (the depth's noise)
    between their two neighbours in a row and in a column (z before + z after - 2 z: a surface's depth runs on
    straight, however steep, and bends at an edge), or differs by less from their one neighbour with depth, joined
    through their 4-neighbours. Flying pixels
    (depths between an edge's two sides) are left out with the edge: through them, a surface would reach over a step
    a few centimetres deep to the one beyond."""
    z = np.asarray(depth_m, float)
    seen = z > 0
    inside = seen.copy()
    for before, here, after in ((np.s_[:, :-2], np.s_[:, 1:-1], np.s_[:, 2:]), (np.s_[:-2], np.s_[1:-1], np.s_[2:])):
        ahead = np.where(seen[before] & seen[after], (z[before] + z[after]) / 2,
                         np.where(seen[before], z[before], np.where(seen[after], z[after], z[here])))
        inside[here] &= np.abs(ahead - z[here]) < np.where(seen[before] & seen[after], step_m / 2, step_m)
    rows, cols = np.nonzero(inside)
    if len(rows) == 0:
        return inside
    labels = cv2.connectedComponents(inside.astype(np.uint8), connectivity=4)[1]
    nearest = int(np.argmin(np.hypot(rows - pixel[0], cols - pixel[1])))
    return labels == labels[rows[nearest], cols[nearest]]


def box_seed(frame: Frame, robot: np.ndarray, box: tuple[float, float, float, float]) -> tuple[int, int]:
    """The pixel to look for the front from when the user drew a box around it: the pixel nearest the box's centre
    on the box's dominant plane (RANSAC over its depth: a box drawn around a front is mostly that front; its centre
    may be on the handle)."""
    h, w = frame.depth_m.shape
    x0, y0, x1, y1 = (int(round(c)) for c in box)
    window = np.zeros((h, w), bool)
    window[max(y0, 0):max(min(y1, h), 0), max(x0, 0):max(min(x1, w), 0)] = True
    window &= ~robot & (frame.depth_m > 0)
    v, u = np.nonzero(window)
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    if len(u) < MIN_SEED_POINTS:
        return int(centre[0]), int(centre[1])
    step = max(len(u) // 4000, 1)  # a few thousand pixels fit the plane as well as all of them
    points = depth_to_points(frame.depth_m, frame.intrinsics.K, window, frame.T_base_camera)[::step]
    depth = float(np.median(frame.depth_m[window]))
    tolerance = NOISE_SIGMAS * float(D415.sigma_m(depth, frame.intrinsics.fx)) + QUANTUM_M / 2
    inliers = dominant_plane(points, tolerance)
    plane = np.zeros((h, w), np.uint8)
    plane[v[::step][inliers], u[::step][inliers]] = 1
    size = 2 * SEED_RADII_PX[0] + 1  # the pixel's surroundings, where its plane is fitted, on that plane too
    plane = cv2.dilate(plane, np.ones((step, step), np.uint8)) if step > 1 else plane
    inside = cv2.erode(plane, np.ones((size, size), np.uint8))
    rows, cols = np.nonzero(inside if inside.any() else plane)
    best = int(np.argmin(np.hypot(cols - centre[0], rows - centre[1])))
    return int(cols[best]), int(rows[best])


def tilt_deg(normal: np.ndarray) -> float:
    """How far a surface with `normal` is tilted from vertical (deg)."""
    return float(np.degrees(np.arcsin(min(abs(float(normal @ UP)) / np.linalg.norm(normal), 1.0))))


def _flat_surface(frame: Frame, robot: np.ndarray, point: np.ndarray) -> str:
    """What a horizontal surface at `point` is: the floor when almost nothing in view lies lower, else a counter, a
    table or a shelf top."""
    points = depth_to_points(frame.depth_m[::4, ::4], np.diag([0.25, 0.25, 1.0]) @ frame.intrinsics.K,
                             ~robot[::4, ::4], frame.T_base_camera)
    lower = np.count_nonzero(points[:, 2] < point[2] - FLOOR_STEP_M)
    return "the floor" if lower < FLOOR_SHARE * max(len(points), 1) else "a counter, table or shelf top"


def refine_plane(frame: Frame, robot: np.ndarray, point: np.ndarray, normal: np.ndarray,
                 depth: float) -> tuple[np.ndarray, np.ndarray]:
    """The vertical plane through the surface around `point` fitted to the depth within REFINE_RADIUS_M: each round
    keeps the points within the noise plus a slope (REFINE_SLOPES_DEG) of their distance, and refits (least squares,
    the normal horizontal: fronts are vertical, and the calibration's up is good to its 0.5 deg)."""
    K = frame.intrinsics
    reach_px = int(K.fx * REFINE_RADIUS_M / depth)
    T_inv = np.linalg.inv(np.asarray(frame.T_base_camera, float))
    pc = T_inv[:3, :3] @ point + T_inv[:3, 3]
    u, v = int(pc[0] / pc[2] * K.fx + K.cx), int(pc[1] / pc[2] * K.fy + K.cy)
    h, w = frame.depth_m.shape
    window = np.zeros((h, w), bool)
    window[max(v - reach_px, 0):v + reach_px + 1:2, max(u - reach_px, 0):u + reach_px + 1:2] = True
    window &= ~robot & (frame.depth_m > 0)
    points = depth_to_points(frame.depth_m, K.K, window, frame.T_base_camera)
    if len(points) < MIN_SEED_POINTS:
        return point, normal
    camera = np.asarray(frame.T_base_camera, float)[:3, 3]
    z = np.linalg.norm(points - camera, axis=1)
    noise = NOISE_SIGMAS * D415.sigma_m(z, K.fx) + QUANTUM_M
    for slope in REFINE_SLOPES_DEG:
        distance = np.linalg.norm(points - point, axis=1)
        keep = (distance < REFINE_RADIUS_M) & (np.abs((points - point) @ normal) < noise + distance * np.tan(
            np.radians(slope)))
        if np.count_nonzero(keep) < MIN_SEED_POINTS:
            break
        centre = points[keep].mean(axis=0)
        fitted = np.zeros(3)  # fronts are vertical: the normal is horizontal, the line the points make seen from above
        fitted[:2] = np.linalg.svd((points[keep] - centre)[:, :2], full_matrices=False)[2][1]
        normal = fitted if fitted @ normal >= 0 else -fitted
        point = point - ((point - centre) @ normal) * normal  # the seed's point, moved onto the new plane
    return point, normal


def visible_range(frame: Frame, plane: PlaneFrame) -> tuple[tuple[float, float], tuple[float, float]]:
    """The plane coordinates (s, z) the image can show, within the largest front's size either way of the origin."""
    h, w = frame.depth_m.shape
    border = np.concatenate([np.stack([np.linspace(0, w - 1, 33), np.full(33, y)], 1) for y in (0, h - 1)]
                            + [np.stack([np.full(25, x), np.linspace(0, h - 1, 25)], 1) for x in (0, w - 1)])
    T = np.asarray(frame.T_base_camera, float)
    rays = (T[:3, :3] @ np.linalg.solve(frame.intrinsics.K, np.c_[border, np.ones(len(border))].T)).T
    camera = T[:3, 3]
    along = rays @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((plane.origin - camera) @ plane.normal) / along
    limits = np.array([MAX_FRONT_WIDTH_M, MAX_FRONT_HEIGHT_M])
    hits = t > 0
    if not hits.all():  # some of the image's border never meets the plane: the view reaches the limits there
        return (-limits[0], limits[0]), (-limits[1], limits[1])
    sz = plane.coordinates(camera + t[:, None] * rays)[:, :2]
    lo, hi = np.maximum(sz.min(axis=0), -limits), np.minimum(sz.max(axis=0), limits)
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def front_plane(frame: Frame, robot: np.ndarray, u: int, v: int) -> tuple[PlaneFrame, float]:
    """The plane frame of the vertical surface at pixel (u, v) (origin where the pixel's ray meets it) and the depth
    there; PointerError for a surface that is not vertical (the floor, a counter top, a slanted face)."""
    point, normal, depth = seed_plane(frame, robot, u, v)
    tilt = tilt_deg(normal)
    if tilt > FLAT_TILT_DEG:
        where = "below" if point[2] < 0 else "above"
        raise PointerError(f"pixel ({u}, {v}) is on {_flat_surface(frame, robot, point)} ({abs(point[2]):.2f} m "
                           f"{where} the arm's base, tilted {tilt:.0f} deg from vertical), not on a front: point at "
                           "the drawer's or door's front panel")
    if tilt > FRONT_TILT_DEG:
        raise PointerError(f"pixel ({u}, {v}) is on a surface tilted {tilt:.0f} deg from vertical, not on a front "
                           f"(fronts are vertical, within {FRONT_TILT_DEG:.0f} deg): point at the drawer's or door's "
                           "front panel")
    normal = np.array([normal[0], normal[1], 0.0]) / np.linalg.norm(normal[:2])
    point, normal = refine_plane(frame, robot, point, normal, depth)
    camera, ray = pixel_ray(frame, u, v)
    origin = camera + ray * ((point - camera) @ normal) / (ray @ normal)
    return PlaneFrame.facing(origin, normal, camera), depth


def find_front(frame: Frame, robot: np.ndarray, u: int, v: int,
               box: tuple[float, float, float, float] | None = None) -> Front:
    """The front at pixel (u, v) (see the module docstring), within the user's `box` (pixels) when given."""
    plane, depth = front_plane(frame, robot, u, v)
    s_range, z_range = visible_range(frame, plane)
    res_m = depth / frame.intrinsics.fx  # a cell is about a pixel at the seed
    view = rectify(frame, robot, plane, s_range, z_range, res_m)
    seed = (int(view.row(0.0)), int(view.col(0.0)))
    own = seed_surface(view, seed)
    if own is not None:  # the plane misses the front's own surface at the seed: turned and moved onto it
        plane = on_seed_surface(frame, plane, own, u, v)
        view = rectify(frame, robot, plane, s_range, z_range, res_m)
    pockets = enclosed_pockets(view)  # a pull's pocket is crossed like a handle
    extent = front_extent(view, seed, pockets)
    framed = framed_panel(view, extent)
    if framed is not None:  # a panel set into its front's frame: the front is the frame's rectangle and plane
        extent, level = framed
        plane = PlaneFrame(plane.point(0.0, 0.0, level), plane.normal, plane.right, plane.up)
        view = rectify(frame, robot, plane, s_range, z_range, res_m)
        pockets = enclosed_pockets(view)

    def blobs_of(extent: Extent) -> list[Blob]:
        return handle_blobs(view, extent, frame.T_base_camera, frame.intrinsics.K)

    narrowed = split_wide(view, extent)
    extent = extent if narrowed == extent else rows_over_columns(view, seed, narrowed, pockets)
    blobs = blobs_of(extent)
    split = split_by_handles(view, extent, blobs)
    extent, blobs = split, (blobs if split == extent else blobs_of(split))
    if own_blob(blobs, view, extent) is None:
        extent = past_stile_line(view, extent, seed, pockets, blobs_of)
    if box is not None:
        extent = _clipped(frame, view, extent, box)
    s0, s1 = view.s(extent.left - 0.5), view.s(extent.right + 0.5)
    z1, z0 = view.z(extent.top - 0.5), view.z(extent.bottom + 0.5)
    centre = plane.point((s0 + s1) / 2, (z0 + z1) / 2)
    centred = PlaneFrame(centre, plane.normal, plane.right, plane.up)
    corners = plane.point(np.array([s0, s1, s1, s0]), np.array([z1, z1, z0, z0]))
    mask = front_pixels(frame, robot, plane, (s0, s1), (z0, z1))
    return Front(centred, float(s1 - s0), float(z1 - z0), corners, mask, dict(extent.ended), view, extent)


def on_seed_surface(frame: Frame, plane: PlaneFrame, own: tuple[float, float], u: int, v: int) -> PlaneFrame:
    """The vertical plane of the surface at offset `own` = (level, slope): level + slope * s from `plane` (the
    front's own surface along the seed's rows: seed_surface.py), its origin where the pixel (u, v)'s ray meets it."""
    level, slope = own
    normal = plane.normal - slope * plane.right
    normal /= np.linalg.norm(normal)
    camera, ray = pixel_ray(frame, u, v)
    origin = camera + ray * ((plane.origin + level * plane.normal - camera) @ normal) / (ray @ normal)
    return PlaneFrame.facing(origin, normal, camera)


def past_stile_line(view: PlaneView, extent: Extent, seed: tuple[int, int], crossed: np.ndarray,
                    blobs_of: Callable[[Extent], list[Blob]]) -> Extent:
    """The rectangle of a front that shows no handle grown past a side line with a handle just beyond it: a door's
    handle sits on its stile by the opening edge, and a frame's inner line (a glass pane's, a panel's) bounding the
    stile is taken for the door's side as a gap would be. Looked for past a left or right side that ended at a gap,
    within NARROW_FRONT_M (a strip narrower than any front is no front of its own): a firm handle beside the
    rectangle. The front is grown again through the strip up to the handle's far edge (no gap looked for there),
    then cut between handles (`split_by_handles`); it is taken when it holds the handle as its own and its new side
    lies within NARROW_FRONT_M past the handle's centre (a handle sits by its front's opening edge: a side farther
    past it is another front's, whose handle this is). Among several: the handle nearest the seed."""
    reach = int(round(NARROW_FRONT_M / view.res_m))
    found = []
    for side, step in (("left", -1), ("right", 1)):
        line = getattr(extent, side)
        if extent.ended.get(side) != "gap":
            continue
        beyond = replace(extent, **{side: int(np.clip(line + step * reach, 0, view.shape[1] - 1))})
        for blob in blobs_of(beyond):
            col, row = float(view.col(blob.centre[0])), float(view.row(blob.centre[1]))
            if not blob.firm or not extent.top <= row <= extent.bottom or (col - line) * step <= 0:
                continue
            far = int(blob.cols.min() if step < 0 else blob.cols.max())
            strip = np.zeros(view.shape, bool)
            strip[extent.top:extent.bottom + 1, min(line, far):max(line, far) + 1] = True
            grown = split_wide(view, front_extent(view, seed, crossed, strip))
            grown = split_by_handles(view, grown, blobs_of(grown))
            past = (getattr(grown, side) - col) * step
            if 0 <= past < reach and own_blob(blobs_of(grown), view, grown) is not None:
                found.append((segment_distance(blob, np.zeros(2)), grown))
    return min(found, key=lambda f: f[0])[1] if found else extent


def _clipped(frame: Frame, view: PlaneView, extent: Extent, box: tuple[float, float, float, float]) -> Extent:
    """`extent` within the user's box: the box's corners seen on the plane bound it (sides the box cuts end "box")."""
    x0, y0, x1, y1 = box
    corners = []
    for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
        camera, ray = pixel_ray(frame, x, y)
        along = ray @ view.plane.normal
        if along >= -1e-6:  # a corner's ray misses the plane: the box does not bound it there
            return extent
        corners.append(camera + ray * ((view.plane.origin - camera) @ view.plane.normal) / along)
    sz = view.plane.coordinates(np.array(corners))
    cols = view.col(np.array([sz[:, 0].min(), sz[:, 0].max()]))
    rows = view.row(np.array([sz[:, 1].max(), sz[:, 1].min()]))
    ended = dict(extent.ended)
    top, bottom, left, right = extent.top, extent.bottom, extent.left, extent.right
    if rows[0] > top:
        top, ended["top"] = int(rows[0]), "box"
    if rows[1] < bottom:
        bottom, ended["bottom"] = int(rows[1]), "box"
    if cols[0] > left:
        left, ended["left"] = int(cols[0]), "box"
    if cols[1] < right:
        right, ended["right"] = int(cols[1]), "box"
    return Extent(top, bottom, left, right, ended)


def front_pixels(frame: Frame, robot: np.ndarray, plane: PlaneFrame, s_range: tuple[float, float],
                 z_range: tuple[float, float]) -> np.ndarray:
    """The image's pixels whose ray meets the plane inside the rectangle and whose depth lies on the plane (or is
    missing, or lies at most a pull's pocket behind it), not the arm's: the front's pixels, its handle left out."""
    h, w = frame.depth_m.shape
    K = frame.intrinsics
    T = np.asarray(frame.T_base_camera, float)
    n_cam = T[:3, :3].T @ plane.normal
    o_cam = T[:3, :3].T @ (plane.origin - T[:3, 3])
    r_cam, u_cam = T[:3, :3].T @ plane.right, T[:3, :3].T @ plane.up
    x = (np.arange(w) - K.cx) / K.fx
    y = (np.arange(h) - K.cy) / K.fy
    along = n_cam[0] * x[None, :] + n_cam[1] * y[:, None] + n_cam[2]  # n . ray per unit depth
    with np.errstate(divide="ignore", invalid="ignore"):
        zp = (o_cam @ n_cam) / along  # the plane's depth along each pixel's ray
        d = (x[None, :] * zp - o_cam[0], y[:, None] * zp - o_cam[1], zp - o_cam[2])  # from the origin, camera frame
        s = d[0] * r_cam[0] + d[1] * r_cam[1] + d[2] * r_cam[2]
        z = d[0] * u_cam[0] + d[1] * u_cam[1] + d[2] * u_cam[2]
        inside = (zp > 0) & (s >= s_range[0]) & (s <= s_range[1]) & (z >= z_range[0]) & (z <= z_range[1])
        depth = frame.depth_m
        tolerance = NOISE_SIGMAS * D415.sigma_m(zp, K.fx) + QUANTUM_M
        on_front = (depth <= 0) | ((depth >= zp - tolerance) & (depth <= zp + tolerance + MAX_POCKET_M / np.abs(along)))
    return inside & on_front & ~robot



def plane_coordinates(plane: PlaneFrame, depth_m: np.ndarray, K: np.ndarray,
                      T_base_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s, z, offset) images (m) of every pixel's measured point in `plane`'s frame (NaN where there is no depth)."""
    h, w = depth_m.shape
    T = np.asarray(T_base_camera, float)
    depth = np.where(depth_m > 0, depth_m, np.nan).astype(np.float64)
    x = (np.arange(w) - K[0, 2]) / K[0, 0]
    y = (np.arange(h) - K[1, 2]) / K[1, 1]
    out = []
    for axis in (plane.right, plane.up, plane.normal):
        a = T[:3, :3].T @ axis  # the axis in the camera frame
        out.append(depth * (a[0] * x[None, :] + a[1] * y[:, None] + a[2]) + (T[:3, 3] - plane.origin) @ axis)
    return out[0], out[1], out[2]
