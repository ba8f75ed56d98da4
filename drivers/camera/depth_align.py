"""Depth re-projected onto the colour image without the holes of rounding, through the colour lens's distortion.

librealsense's `rs.align` maps each depth pixel's corners into the colour image and rounds them so that
neighbouring footprints do not always meet: on a recording whose depth and colour already share one pixel grid
it leaves whole columns and rows empty (5 % of the pixels of a 64x48 image). Its x86 build (SSSE3) also projects
into a colour image with (inverse) Brown-Conrady distortion as if it had none (src/proc/align.cpp distorts only
for the modified model), so on a D455, D405 or L515 its depth lands pixels away from the colour it belongs to near
the image's edges, while its plain build distorts. `DepthAligner` instead:

- passes depth through unchanged when the two cameras co-register (identity extrinsics, equal intrinsics);
- otherwise splats every depth pixel onto the colour pixels whose centres lie in its footprint (the projected
  pixel square, half-open, so the footprints of neighbours on one surface tile the image), keeping the nearest
  surface per colour pixel (z-buffer), and then closes the one-pixel seams between two footprints that come
  from neighbouring depth pixels on one surface (depths within `SEAM_TOLERANCE`). What stays empty is what
  the re-projection really uncovers: colour pixels beside an occluding edge that the depth camera did not see,
  and those outside its field of view.

Pixels of a lens with distortion map to rays through OpenCV's inversion of its model, and points to the colour
image through the model itself (`Intrinsics.dist_coeffs`, as librealsense's own projection does). The depth value is
the point's z in the colour camera's frame, so the colour intrinsics (lens included) deproject it.
"""

from __future__ import annotations

import cv2
import numpy as np

from drivers.camera.base import Intrinsics

SEAM_TOLERANCE = 0.03  # relative depth difference of two neighbouring depth pixels taken to be one surface
_COREGISTERED_M = 1e-6  # translation below this and rotation within 1e-9 of identity: one pixel grid


class DepthAligner:
    """Aligns depth images of intrinsics `depth` to colour of intrinsics `color`; `R`, `t` map points of the
    depth camera's frame into the colour camera's (metres)."""

    def __init__(self, depth: Intrinsics, color: Intrinsics, R: np.ndarray, t: np.ndarray) -> None:
        self.depth, self.color = depth, color
        R, self.t = np.asarray(R, float).reshape(3, 3), np.asarray(t, float).reshape(3)
        same_lens = (np.array_equal(depth.K, color.K) and (depth.width, depth.height) == (color.width, color.height)
                     and depth.coeffs == color.coeffs)
        self.coregistered = (same_lens and np.allclose(R, np.eye(3), atol=1e-9)
                             and float(np.linalg.norm(self.t)) < _COREGISTERED_M)
        self._dist = None if color.dist_coeffs is None else color.dist_coeffs.astype(np.float32)
        rows, cols = np.mgrid[0:depth.height, 0:depth.width]
        x, y = cols.ravel().astype(float), rows.ravel().astype(float)
        # the rays through each depth pixel's first corner, centre and last corner, turned into the colour frame
        self._rays = [(R @ _rays(depth, x + dx, y + dx)).astype(np.float32) for dx in (-0.5, 0.0, 0.5)]

    def _project(self, ray: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Colour pixel coordinates (u, v) of the points at depth `z` along `ray` (rays of the valid pixels)."""
        c, t = self.color, self.t
        zc = ray[2] * z + np.float32(t[2])
        x, y = (ray[0] * z + np.float32(t[0])) / zc, (ray[1] * z + np.float32(t[1])) / zc
        if self._dist is not None:
            x, y = _distort(x, y, self._dist)
        return c.fx * x + c.cx, c.fy * y + c.cy

    def align(self, depth_m: np.ndarray) -> np.ndarray:
        """(H_depth, W_depth) metres (0 = none) -> (H_color, W_color) float32 metres on the colour grid."""
        depth_m = np.asarray(depth_m, np.float32)
        if self.coregistered:
            return depth_m.copy()
        z = depth_m.ravel()
        valid = np.flatnonzero(z > 0)
        z = z[valid]
        first, centre, last = (ray[:, valid] for ray in self._rays)
        zc = centre[2] * z + np.float32(self.t[2])
        u0, v0 = self._project(first, z)
        u1, v1 = self._project(last, z)
        first_u, first_v = np.ceil(np.minimum(u0, u1)).astype(np.int32), np.ceil(np.minimum(v0, v1)).astype(np.int32)
        count_u = np.ceil(np.maximum(u0, u1)).astype(np.int32) - first_u
        count_v = np.ceil(np.maximum(v0, v1)).astype(np.int32) - first_v
        w, h = self.color.width, self.color.height
        nearest = np.full(h * w, np.inf, np.float32)
        source = np.full(h * w, -1, np.int64)
        for du in range(int(count_u.max(initial=0))):
            for dv in range(int(count_v.max(initial=0))):
                u, v = first_u + du, first_v + dv
                hit = np.flatnonzero((zc > 0) & (du < count_u) & (dv < count_v) & (u >= 0) & (u < w) & (v >= 0)
                                     & (v < h))
                target = v[hit] * w + u[hit]
                np.minimum.at(nearest, target, zc[hit])
                won = nearest[target] == zc[hit]
                source[target[won]] = valid[hit[won]]
        out = np.where(np.isfinite(nearest), nearest, np.float32(0)).reshape(h, w)
        _close_seams(out, source.reshape(h, w), self.depth.width)
        return out


def _close_seams(out: np.ndarray, source: np.ndarray, depth_width: int) -> None:
    """Fill (in place) each empty pixel whose two neighbours along a row or a column hold depth from
    neighbouring depth pixels of one surface, with their mean."""
    h, w = out.shape
    for step in ((0, 1), (1, 0)):
        rows, cols = np.nonzero(out == 0)
        inner = (rows >= step[0]) & (rows < h - step[0]) & (cols >= step[1]) & (cols < w - step[1])
        rows, cols = rows[inner], cols[inner]
        a, b = (rows - step[0], cols - step[1]), (rows + step[0], cols + step[1])
        za, zb, sa, sb = out[a], out[b], source[a], source[b]
        ya, xa = np.divmod(sa, depth_width)
        yb, xb = np.divmod(sb, depth_width)
        near = np.minimum(za, zb)
        seam = ((sa >= 0) & (sb >= 0) & (np.abs(ya - yb) <= 1) & (np.abs(xa - xb) <= 1) & (near > 0)
                & (np.abs(za - zb) <= SEAM_TOLERANCE * near))
        out[rows[seam], cols[seam]] = (za[seam] + zb[seam]) / 2
        source[rows[seam], cols[seam]] = sa[seam]


def _rays(intrinsics: Intrinsics, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, N) rays (x / z, y / z, 1) through pixels (u, v) of a camera, its lens's distortion inverted."""
    if intrinsics.dist_coeffs is None:
        x, y = (u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy
    else:
        pixels = np.stack([u, v], axis=-1).reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-9)
        x, y = cv2.undistortPoints(pixels, intrinsics.K, intrinsics.dist_coeffs, criteria=criteria).reshape(-1, 2).T
    return np.stack([x, y, np.ones_like(x)])


def _distort(x: np.ndarray, y: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised image coordinates through OpenCV's distortion model with coefficients (k1, k2, p1, p2, k3)."""
    r2 = x * x + y * y
    radial = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))
    return (x * radial + 2 * k[2] * x * y + k[3] * (r2 + 2 * x * x),
            y * radial + k[2] * (r2 + 2 * y * y) + 2 * k[3] * x * y)
