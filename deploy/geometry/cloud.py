"""Depth image -> point cloud (metres) and back to pixels, and rigid transforms of point sets.

A camera is its 3x3 pinhole matrix `K` and, for a lens with distortion, OpenCV's distortion vector `dist` (k1, k2,
p1, p2, k3: the Brown-Conrady model RealSense cameras report, which librealsense applies the same way). A pixel
deprojects through OpenCV's iterative inversion of the model (`undistort_pixels`), a point projects through the
model (`project`); `dist` None is a pinhole camera.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-9)  # iterations; normalised-plane step


def undistort_pixels(uv: np.ndarray, K: np.ndarray, dist: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) pixel coordinates -> (N, 2) coordinates (x / z, y / z) of the rays through them, in the camera frame."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    K = np.asarray(K, np.float64)
    if dist is None:
        return (uv - K[:2, 2]) / [K[0, 0], K[1, 1]]
    undistorted = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, np.asarray(dist, np.float64), None, None,
                                      criteria=UNDISTORT_CRITERIA)
    return undistorted.reshape(-1, 2)


@functools.lru_cache(maxsize=8)
def _ray_grid(shape: tuple[int, int], K: tuple[float, ...], dist: tuple[float, ...]) -> np.ndarray:
    """(H, W, 2) ray coordinates (x / z, y / z) of every pixel of an image of `shape` (kept: a camera's frames share
    them)."""
    v, u = np.mgrid[0:shape[0], 0:shape[1]]
    rays = undistort_pixels(np.column_stack([u.ravel(), v.ravel()]), np.reshape(K, (3, 3)), np.array(dist))
    rays = rays.reshape(*shape, 2)
    rays.flags.writeable = False
    return rays


def project(points_camera: np.ndarray, K: np.ndarray, dist: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) pixel coordinates of (N, 3) points in the camera frame (OpenCV: x right, y down, z forward); NaN for
    points at or behind the camera."""
    cam = np.asarray(points_camera, np.float64).reshape(-1, 3)
    z = np.where(cam[:, 2] > 1e-6, cam[:, 2], np.nan)
    xy = cam[:, :2] / z[:, None]
    K = np.asarray(K, np.float64)
    if dist is not None:
        ahead = np.isfinite(z)
        distorted = cv2.projectPoints(np.column_stack([xy[ahead], np.ones(int(ahead.sum()))]), np.zeros(3),
                                      np.zeros(3), np.eye(3), np.asarray(dist, np.float64))[0].reshape(-1, 2)
        xy[ahead] = distorted
    return xy * [K[0, 0], K[1, 1]] + K[:2, 2]


def depth_to_points(
    depth_m: np.ndarray,
    K: np.ndarray,
    mask: np.ndarray | None = None,
    T_base_camera: np.ndarray | None = None,
    min_depth_m: float = 0.0,
    max_depth_m: float = np.inf,
    dist: np.ndarray | None = None,
) -> np.ndarray:
    """Back-project a metric depth image to (N,3) points, in row-major pixel order.

    K is the 3x3 pinhole matrix (OpenCV camera frame: x right, y down, z forward), `dist` the lens's distortion
    (None: pinhole). Pixels with invalid depth (0, NaN, inf, outside [min_depth_m, max_depth_m]) or outside `mask`
    are dropped. With the 4x4 pose `T_base_camera` the points are returned in the base frame, else in the camera
    frame.
    """
    depth = np.asarray(depth_m, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    if depth.ndim != 2:
        raise ValueError(f"depth_to_points: depth must be an (H, W) image, got shape {depth.shape}")
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or abs(np.linalg.det(K)) < 1e-12:
        raise ValueError(f"depth_to_points: K must be an invertible 3x3 pinhole matrix, got {K.tolist()}")
    valid = np.isfinite(depth) & (depth > 0) & (depth >= min_depth_m) & (depth <= max_depth_m)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != depth.shape:
            raise ValueError(
                f"depth_to_points: mask shape {mask.shape} differs from depth shape {depth.shape}; "
                "align the mask to the depth image"
            )
        valid &= mask.astype(bool)
    v, u = np.nonzero(valid)
    z = depth[v, u]
    if dist is None:
        pixels = np.stack([u, v, np.ones_like(u)], axis=1).astype(np.float64)
        points = (pixels @ np.linalg.inv(K).T) * z[:, None]
    else:
        rays = _ray_grid(depth.shape, tuple(K.ravel()), tuple(np.asarray(dist, np.float64)))
        points = np.column_stack([rays[v, u] * z[:, None], z])
    return points if T_base_camera is None else transform_points(T_base_camera, points)


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply the 4x4 rigid transform T to (N,3) points."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"transform_points: T must be a 4x4 homogeneous transform, got shape {T.shape}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points @ T[:3, :3].T + T[:3, 3]


def points_to_pixels(points: np.ndarray, K: np.ndarray, T_base_camera: np.ndarray | None = None,
                     dist: np.ndarray | None = None) -> np.ndarray:
    """Pixel coordinates (N, 2) of (N, 3) points through the camera `K`, `dist` (OpenCV camera frame), the points
    given in the base frame when the camera's pose `T_base_camera` is, else in the camera frame; NaN for points
    behind it."""
    T = np.eye(4) if T_base_camera is None else np.linalg.inv(np.asarray(T_base_camera, float))
    return project(np.asarray(points, float).reshape(-1, 3) @ T[:3, :3].T + T[:3, 3], K, dist)
