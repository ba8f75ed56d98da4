"""Oriented boxes of point clouds (z up), the cabinet's front direction, and handle removal."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import open3d as o3d
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.transform import Rotation

from deploy.geometry.types import Box

_FACE_BIN_M = 0.005
_FACE_FRACTION = 0.25  # a bin holding this share of the densest bin is a face, not a protrusion


def yaw_box(points: np.ndarray, n_angles: int | None = 120) -> Box:
    """Smallest-area box in top view with vertical sides (the paper's yaw-only box), rotation = Rz(yaw).

    Tries `n_angles` yaw angles evenly over [0, pi/2) as the paper's code does; `n_angles=None` tries
    the hull edge directions instead, which gives the exact minimum. Only the 2D convex hull of the
    xy points is searched, which gives the same box. First axis = the longer horizontal side.
    """
    if n_angles is not None and n_angles < 1:
        raise ValueError(f"yaw_box: n_angles must be >= 1 (or None for the exact box), got {n_angles}")
    pts = _finite(points, "yaw_box")
    hull = _hull_xy(pts[:, :2])
    if n_angles is None:
        edges = np.roll(hull, -1, axis=0) - hull
        angles = np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2)
    else:
        angles = np.pi / 2 * np.arange(n_angles) / n_angles
    cos, sin = np.cos(angles), np.sin(angles)
    u = hull[:, :1] * cos + hull[:, 1:] * sin  # (hull points, angles): coordinates along each yaw
    v = -hull[:, :1] * sin + hull[:, 1:] * cos
    best = int(np.argmin(np.ptp(u, axis=0) * np.ptp(v, axis=0)))
    yaw, u, v = angles[best], u[:, best], v[:, best]
    length_u, length_v = np.ptp(u), np.ptp(v)
    mid_u, mid_v = (u.max() + u.min()) / 2, (v.max() + v.min()) / 2
    center_xy = mid_u * np.array([np.cos(yaw), np.sin(yaw)]) + mid_v * np.array([-np.sin(yaw), np.cos(yaw)])
    if length_v > length_u:
        yaw, length_u, length_v = yaw + np.pi / 2, length_v, length_u
    z_lo, z_hi = pts[:, 2].min(), pts[:, 2].max()
    return Box(
        center=np.array([center_xy[0], center_xy[1], (z_lo + z_hi) / 2]),
        rotation=_rot_z(yaw),
        extent=np.array([length_u, length_v, z_hi - z_lo]),
    )


def front_box(points: np.ndarray, viewpoint: np.ndarray, tolerance_m: float = 0.005) -> Box:
    """Box with vertical sides turned to the cabinet's front: its yaw follows the normal of the largest
    vertical plane in the points (RANSAC, `tolerance_m`); extents and centre from all points. First axis =
    the longer horizontal side. Falls back to `yaw_box` when no vertical plane holds a fifth of the points.

    A front seen head-on with its sides lost to grazing-angle dropout (a stereo camera's usual view) leaves
    the smallest-area box ill-posed: a few top or base points turn it by degrees; the front's plane does not.
    """
    pts = _finite(points, "front_box")
    normal = _vertical_plane_normal(pts, tolerance_m)
    if normal is None:
        return yaw_box(pts)
    yaw = float(np.arctan2(normal[1], normal[0]))
    local = pts @ _rot_z(yaw)
    lo, hi = local.min(axis=0), local.max(axis=0)
    if hi[1] - lo[1] > hi[0] - lo[0]:
        yaw += np.pi / 2
        local = pts @ _rot_z(yaw)
        lo, hi = local.min(axis=0), local.max(axis=0)
    rotation = _rot_z(yaw)
    return Box(center=rotation @ ((lo + hi) / 2), rotation=rotation, extent=hi - lo)


def _vertical_plane_normal(points: np.ndarray, tolerance_m: float, tries: int = 3) -> np.ndarray | None:
    """Unit horizontal normal of the largest near-vertical plane (|n_z| < 0.2), None if none is large."""
    o3d.utility.random.seed(0)
    remaining = points
    for _ in range(tries):
        if len(remaining) < max(30, 0.2 * len(points)):
            return None
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
        plane, inliers = cloud.segment_plane(tolerance_m, 3, 300)
        normal = np.asarray(plane[:3], float)
        normal /= np.linalg.norm(normal)
        if abs(normal[2]) < 0.2 and len(inliers) >= 0.2 * len(points):
            horizontal = np.array([normal[0], normal[1], 0.0])
            return horizontal / np.linalg.norm(horizontal)
        remaining = np.delete(remaining, inliers, axis=0)
    return None


def oriented_box(points: np.ndarray) -> Box:
    """Minimal-volume 3D oriented box (Open3D), with a right-handed rotation.

    Open3D's minimal box sometimes comes back all-zero: then it is retried with Open3D's joggled
    (robust) variant, and finally replaced by the PCA box. Flat, collinear or tiny input gets the PCA
    box directly (computed here: Open3D's Qhull-based boxes fail on it).
    """
    pts = _finite(points, "oriented_box")
    spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if len(pts) < 4 or spread[-1] <= 1e-9 * spread[0]:  # flat, collinear or a point: Qhull cannot help
        return _pca_box(pts)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    for robust in (False, True):
        try:
            obb = cloud.get_minimal_oriented_bounding_box(robust=robust)
        except RuntimeError:  # Qhull: flat or too few points
            continue
        if np.prod(obb.extent) > 0:
            return _right_handed(np.asarray(obb.center), np.asarray(obb.R), np.asarray(obb.extent))
    return _pca_box(pts)


def front_direction(box: Box, viewpoint: np.ndarray) -> np.ndarray:
    """Unit outward normal of the box's vertical face that looks at `viewpoint` (the cabinet's front).

    Of the two most horizontal box axes, the face chosen is the one the ray from the box centre to the
    viewpoint (camera position or robot base origin) leaves through in top view.
    """
    axes = np.argsort(np.abs(box.rotation[2]))[:2]
    local = (np.asarray(viewpoint, dtype=np.float64) - box.center) @ box.rotation[:, axes]
    reach = np.abs(local) / np.maximum(box.extent[axes] / 2, 1e-9)
    k = int(np.argmax(reach))
    return box.rotation[:, axes[k]] * (1.0 if local[k] >= 0 else -1.0)


def extend_behind(box: Box, front: np.ndarray, depth_m: float) -> Box:
    """`box` reaching `depth_m` further behind its face whose outward normal is nearest `front` (to cover
    a cabinet's inside, which an opening door reveals and which does not move)."""
    k = int(np.argmax(np.abs(box.rotation.T @ np.asarray(front, dtype=np.float64))))
    axis = box.rotation[:, k] * np.sign(box.rotation[:, k] @ front)
    extent = box.extent.copy()
    extent[k] += depth_m
    return Box(box.center - axis * depth_m / 2, box.rotation, extent)


def front_face_depth(depth: np.ndarray) -> float:
    """Where the front face lies along a normal, given the points' depths along it (m): the median of the
    outermost 5 mm layer holding at least a quarter of the densest layer's points (a handle or other
    protrusion in front of it holds fewer)."""
    depth = np.asarray(depth, dtype=np.float64)
    n_bins = max(1, int(np.ceil((depth.max() - depth.min()) / _FACE_BIN_M)))
    counts, edges = np.histogram(depth, bins=n_bins, range=(depth.min(), depth.min() + n_bins * _FACE_BIN_M))
    face_bin = np.flatnonzero(counts >= _FACE_FRACTION * counts.max())[-1]
    in_bin = (depth >= edges[face_bin]) & (depth <= edges[face_bin + 1])
    return float(np.median(depth[in_bin]))


def remove_handle(
    points: np.ndarray,
    viewpoint: np.ndarray,
    box_fn: Callable[[np.ndarray], Box] = yaw_box,
    margin_m: float = 0.008,
) -> tuple[Box, np.ndarray, np.ndarray]:
    """Split a cabinet cloud into body and handle: returns (body_box, body_points, handle_points).

    Along the front normal the front face is found by `front_face_depth`; points more than `margin_m` in
    front of it are the handle (and other protrusions) and the body box is refitted without them.
    No handle: the box is returned unchanged.
    """
    pts = _finite(points, "remove_handle")
    box = box_fn(pts)
    depth = (pts - box.center) @ front_direction(box, viewpoint)
    handle = depth > front_face_depth(depth) + margin_m
    if not handle.any():
        return box, pts, pts[:0]
    return box_fn(pts[~handle]), pts[~handle], pts[handle]


def _finite(points: np.ndarray, who: str) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        raise ValueError(f"{who}: no finite points to fit a box to; check the segmentation mask and depth")
    return pts


def _hull_xy(xy: np.ndarray) -> np.ndarray:
    """Convex hull vertices of 2D points (all points when the hull is degenerate: collinear, < 3)."""
    try:
        return xy[ConvexHull(xy).vertices]
    except (QhullError, ValueError):
        return xy


def _rot_z(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _right_handed(center: np.ndarray, rotation: np.ndarray, extent: np.ndarray) -> Box:
    """Box with the nearest proper rotation (last axis flipped if left-handed, then re-orthonormalised)."""
    rotation = rotation * [1.0, 1.0, np.sign(np.linalg.det(rotation)) or 1.0]
    rotation = Rotation.from_matrix(rotation).as_matrix()
    return Box(center=center.copy(), rotation=rotation, extent=extent.copy())


def _pca_box(pts: np.ndarray) -> Box:
    rotation = np.linalg.svd(pts - pts.mean(axis=0))[2].T  # principal axes (3x3 even for one point)
    local = pts @ rotation
    lo, hi = local.min(axis=0), local.max(axis=0)
    return _right_handed(rotation @ ((lo + hi) / 2), rotation, hi - lo)
