"""Camera rays and what they meet: pinhole ray grids, the pixels that can see the moving links, and the geometry
of the hits of a set of pixels (`Surface`: flat arrays, one entry per hit pixel; coordinates as (3, n) arrays so
that elementwise numpy on them stays fast).

Per-triangle quantities are looked up with `Surface.row`: the triangle's index into the scene's table.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from drivers.camera.base import Intrinsics
from sim_fallback.render.scene import Hits, RayScene

NEAR_M = 0.01  # a box reaching nearer than this to the camera plane counts as covering the whole image


def camera_rays(intrinsics: Intrinsics) -> np.ndarray:
    """(H * W, 3) float32 rays through the pixel centres (row by row) in the camera frame (x right, y down,
    z forward), scaled to z = 1 so that a hit's ray parameter is its depth."""
    K = intrinsics
    u = (np.arange(K.width, dtype=np.float32) - np.float32(K.cx)) / np.float32(K.fx)
    v = (np.arange(K.height, dtype=np.float32) - np.float32(K.cy)) / np.float32(K.fy)
    rays = np.ones((len(v), len(u), 3), np.float32)
    rays[..., 0], rays[..., 1] = u[None, :], v[:, None]
    return rays.reshape(-1, 3)


def box_pixels(boxes: np.ndarray, T_world_camera: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Flat indices of the pixels that can see any of the boxes ((n, 8, 3) world corners): inside the convex hull
    of a box's projected corners, grown by a pixel."""
    K = intrinsics
    mask = np.zeros((K.height, K.width), np.uint8)
    T = np.linalg.inv(T_world_camera)
    for corners in boxes:
        cam = corners @ T[:3, :3].T + T[:3, 3]
        if cam[:, 2].max() <= 0:
            continue
        if cam[:, 2].min() < NEAR_M:
            mask[:] = 1
            break
        uv = np.stack([K.fx * cam[:, 0] / cam[:, 2] + K.cx, K.fy * cam[:, 1] / cam[:, 2] + K.cy], axis=1)
        if np.abs(uv).max() > 1e6:
            mask[:] = 1
            break
        hull = cv2.convexHull(np.round(uv * 16).astype(np.int32))
        cv2.fillConvexPoly(mask, hull, 1, lineType=cv2.LINE_8, shift=4)
    mask = cv2.dilate(mask, np.ones((3, 3), np.uint8))
    return np.flatnonzero(mask)


@dataclass
class Surface:
    """The hits of a set of pixels: `index` flat pixel indices; `depth` (ray parameter: metres along the optical
    axis for camera rays); `row` the triangle; `bary` (n, 2) barycentric coordinates in it; `point`, `normal`
    (turned toward the viewer) and `view` (unit, from the point toward the viewer), each (3, n), in the world."""

    index: np.ndarray
    depth: np.ndarray
    row: np.ndarray
    bary: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    view: np.ndarray

    def take(self, k: np.ndarray) -> Surface:
        """The entries at positions `k` (an index array or a boolean mask)."""
        return Surface(self.index[k], self.depth[k], self.row[k], self.bary[k], self.point[:, k], self.normal[:, k],
                       self.view[:, k])

    @staticmethod
    def join(a: Surface, b: Surface) -> Surface:
        """The entries of `a`, then those of `b`."""
        flat = [np.concatenate([x, y]) for x, y in ((a.index, b.index), (a.depth, b.depth), (a.row, b.row),
                                                     (a.bary, b.bary))]
        coords = [np.concatenate([x, y], axis=1) for x, y in ((a.point, b.point), (a.normal, b.normal),
                                                               (a.view, b.view))]
        return Surface(*flat, *coords)

    def interpolate(self, table: np.ndarray) -> np.ndarray:
        """A per-corner quantity at each hit: `table` (triangles, 3) holds each triangle's value at corner 0 and
        its differences to corners 1 and 2."""
        c0, d1, d2 = (table[:, k].take(self.row) for k in range(3))
        return c0 + self.bary[:, 0] * d1 + self.bary[:, 1] * d2


def surface(scene: RayScene, eye: np.ndarray, directions: np.ndarray, index: np.ndarray, hits: Hits) -> Surface:
    """The Surface of the rays from `eye` along `directions` (n, 3) for pixels `index` that `hits` says hit."""
    hit = np.flatnonzero(hits.triangle < len(scene.triangles.link))
    d = directions[hit].T
    t = hits.t[hit]
    row = hits.triangle[hit]
    point = eye[:, None] + t * d
    view = -d / np.sqrt(np.einsum("kn,kn->n", d, d))
    normals = scene.world_normals()
    corner = scene.world_corners()[:, 0] if len(normals) else np.zeros((0, 3), np.float32)
    away = np.einsum("ni,ni->n", normals, corner - eye) > 0  # normals turned toward the viewer
    normals[away] *= -1
    normal = np.stack([np.ascontiguousarray(normals[:, k]).take(row) for k in range(3)])
    return Surface(index[hit], t, row, hits.uv[hit], point, normal, view)
