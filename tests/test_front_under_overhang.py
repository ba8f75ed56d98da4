"""The front plane at the user's pixel on a low drawer front under a counter's overhang, seen from above: the window
around the pixel shows the front and, a step in front of it and above, the counter's edge (a ray-cast synthetic
frame; no simulator)."""

from __future__ import annotations

import numpy as np

from deploy.perception.front import front_plane
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.depth_noise import DepthNoise

K = Intrinsics(640, 480, 500.0, 500.0, 319.5, 239.5)
FRONT = ((1.0, 1.5), (-0.3, 0.3), (0.60, 0.70))  # a 10 cm tall front facing -x ...
COUNTER = ((0.93, 1.6), (-1.5, 1.5), (0.74, 0.78))  # ... under a counter whose edge stands 7 cm out of it
FLOOR = ((-2.0, 3.0), (-3.0, 3.0), (-0.05, 0.0))
WALL = ((1.6, 1.7), (-3.0, 3.0), (0.0, 2.5))


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.column_stack([x, np.cross(z, x), z]), eye
    return T


def _raycast(T: np.ndarray, boxes, sigma: float = 0.002) -> np.ndarray:
    """The depth image (optical z, m) of axis-aligned `boxes` seen from camera pose T, with noise `sigma` z^2."""
    v, u = np.mgrid[0:K.height, 0:K.width]
    rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], -1) @ T[:3, :3].T
    nearest = np.full(u.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for box in boxes:
            lo, hi = np.array(box, float).T
            t0, t1 = (lo - T[:3, 3]) / rays, (hi - T[:3, 3]) / rays
            near, far = np.minimum(t0, t1).max(-1), np.maximum(t0, t1).min(-1)
            hit = (near <= far) & (near > 0)
            nearest = np.where(hit & (near < nearest), near, nearest)
    depth = np.where(np.isfinite(nearest), nearest, 0.0)  # rays have optical z 1: t is the depth
    noise = np.random.default_rng(0).normal(0.0, sigma * depth**2, depth.shape)
    return (depth + noise * (depth > 0)).astype(np.float32)


def test_a_low_front_under_a_counters_edge_seen_from_above_is_vertical():
    """Pointed on the front, 1.2 m away and 50 deg below the camera: the plane joining the front and the counter's
    edge over it (a step apart, each a few pixels tall) is no surface; the front's own is vertical (before: the
    window's plane, tilted 26 deg, was refused as no front)."""
    T = _look_at(np.array([0.31, 0.45, 1.55]), np.array([1.0, 0.0, 0.65]))
    depth = _raycast(T, [FRONT, COUNTER, FLOOR, WALL])
    x, y, z = T[:3, :3].T @ (np.array([1.0, 0.05, 0.62]) - T[:3, 3])  # low on the front (the counter hides its top)
    u, v = int(round(K.fx * x / z + K.cx)), int(round(K.fy * y / z + K.cy))
    frame = Frame(0, 0.0, np.full((480, 640, 3), 120, np.uint8), depth, K, T)
    plane, _ = front_plane(frame, np.zeros(depth.shape, bool), u, v)
    assert plane.normal @ np.array([-1.0, 0.0, 0.0]) > np.cos(np.radians(5))
    assert abs(plane.origin[0] - 1.0) < 0.01



DESK_TOP = ((0.93, 1.6), (-1.5, 1.5), (0.74, 0.78))  # a desk's top, its edge 7 cm out of the front ...
APRON = ((0.97, 1.6), (-1.5, 1.5), (0.70, 0.74))  # ... over a rail 3 cm out of it ...
THIN_FRONT = ((1.0, 1.5), (-0.4, 0.4), (0.62, 0.70))  # ... over an 8 cm tall drawer front


def test_a_thin_front_under_a_desk_top_seen_from_above_in_the_d415s_depth():
    """Pointed on the front, 1.5 m away and 35 deg below the camera, in the D415's depth (drivers.camera.depth_noise):
    the flying pixels along the steps (depths between their two sides) join the top's and the rail's edges to the
    front through points a noise apart, and the window's plane tilts 30-50 deg; the front, cut from them where the
    depth steps, is vertical (before: refused as a counter top or as tilted from vertical)."""
    T = _look_at(np.array([-0.2, 0.35, 1.55]), np.array([1.0, 0.0, 0.66]))
    clean = _raycast(T, [THIN_FRONT, APRON, DESK_TOP, FLOOR, WALL], sigma=0.0)
    frame = Frame(0, 0.0, np.full((480, 640, 3), 120, np.uint8),
                  DepthNoise.d415().apply(clean, K.fx, np.random.default_rng(0)), K, T)
    for height in (0.64, 0.66):  # the front shows below 0.68 m (the rail hides its top)
        x, y, z = T[:3, :3].T @ (np.array([1.0, 0.0, height]) - T[:3, 3])
        u, v = int(round(K.fx * x / z + K.cx)), int(round(K.fy * y / z + K.cy))
        plane, _ = front_plane(frame, np.zeros(clean.shape, bool), u, v)
        assert plane.normal @ np.array([-1.0, 0.0, 0.0]) > np.cos(np.radians(5))
        assert abs(plane.origin[0] - 1.0) < 0.01
