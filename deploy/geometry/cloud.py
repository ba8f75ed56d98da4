"""Depth image -> point cloud (metres) and back to pixels, and rigid transforms of point sets."""

from __future__ import annotations

import numpy as np


def depth_to_points(
    depth_m: np.ndarray,
    K: np.ndarray,
    mask: np.ndarray | None = None,
    T_base_camera: np.ndarray | None = None,
    min_depth_m: float = 0.0,
    max_depth_m: float = np.inf,
) -> np.ndarray:
    """Back-project a metric depth image to (N,3) points, in row-major pixel order.

    K is the 3x3 pinhole matrix (OpenCV camera frame: x right, y down, z forward). Pixels with invalid
    depth (0, NaN, inf, outside [min_depth_m, max_depth_m]) or outside `mask` are dropped. With the
    4x4 pose `T_base_camera` the points are returned in the base frame, else in the camera frame.
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
    pixels = np.stack([u, v, np.ones_like(u)], axis=1).astype(np.float64)
    points = (pixels @ np.linalg.inv(K).T) * z[:, None]
    return points if T_base_camera is None else transform_points(T_base_camera, points)


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply the 4x4 rigid transform T to (N,3) points."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"transform_points: T must be a 4x4 homogeneous transform, got shape {T.shape}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points @ T[:3, :3].T + T[:3, 3]


def points_to_pixels(points: np.ndarray, K: np.ndarray, T_base_camera: np.ndarray | None = None) -> np.ndarray:
    """Pixel coordinates (N, 2) of (N, 3) points through the pinhole `K` (OpenCV camera frame), the points given in
    the base frame when the camera's pose `T_base_camera` is, else in the camera frame; NaN for points behind it."""
    T = np.eye(4) if T_base_camera is None else np.linalg.inv(np.asarray(T_base_camera, float))
    cam = np.asarray(points, float).reshape(-1, 3) @ T[:3, :3].T + T[:3, 3]
    z = np.where(cam[:, 2] > 1e-6, cam[:, 2], np.nan)
    K = np.asarray(K, float)
    return (cam[:, :2] / z[:, None]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
