"""A depth-noise model resembling an Intel RealSense D415 (active IR stereo), for simulated depth.

Each effect is switchable: a zero sigma or rate, `depth_unit_m=0`, `min_range_m=0`, `max_range_m=inf`
or `max_incidence_deg=90` turns it off. The D415's minimum range is about 0.45 m at 1280x720 and less
at lower resolutions (about 0.3 m at 640x480, the default here) or with a disparity shift.

Speed (a 640x480 frame in about 5 ms on one core): the image is processed in float32 (the output
type; its rounding is far below the noise) and in blocks of rows whose temporaries stay in cache,
and flying pixels and holes draw random numbers only for the pixels concerned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

_MAX_DEPTH_M = 1e6  # larger (or inf) is no depth, and squares of smaller ones stay finite in float32
_BLOCK_PX = 32768  # pixels per block of rows: small temporaries stay in cache and are reused
_CROSS = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], np.uint8)  # the 4 neighbours, not the pixel itself


@dataclass(frozen=True)
class DepthNoise:
    """Stereo depth noise.

    axial sigma_z = z^2 * subpixel / (fx * baseline_m) (Intel's RMS-error formula); quantisation to
    `depth_unit_m`; random holes at `hole_rate`; dropout where the view ray meets the surface more
    than `max_incidence_deg` from its normal; flying pixels: a pixel next to a depth jump larger than
    `edge_jump_m` gets, with probability `flying_pixel_rate`, a value between the two sides; depths
    outside [`min_range_m`, `max_range_m`] read 0.
    """

    baseline_m: float = 0.055
    subpixel: float = 0.0
    depth_unit_m: float = 0.0
    hole_rate: float = 0.0
    max_incidence_deg: float = 90.0
    flying_pixel_rate: float = 0.0
    edge_jump_m: float = 0.02
    min_range_m: float = 0.0
    max_range_m: float = math.inf

    @classmethod
    def none(cls) -> DepthNoise:
        """Perfect depth (every effect off)."""
        return cls()

    @classmethod
    def d415(cls) -> DepthNoise:
        """A D415 at 640x480: 0.08 subpixel, 1 mm units, 1 % holes, 0.3-10 m range."""
        return cls(
            subpixel=0.08,
            depth_unit_m=0.001,
            hole_rate=0.01,
            max_incidence_deg=80.0,
            flying_pixel_rate=0.5,
            min_range_m=0.3,
            max_range_m=10.0,
        )

    def sigma_m(self, depth_m: np.ndarray | float, fx: float) -> np.ndarray:
        """Axial noise standard deviation (m) at `depth_m` for focal length `fx` (px)."""
        return np.square(depth_m) * self.subpixel / (fx * self.baseline_m)

    def apply(self, depth_m: np.ndarray, fx: float, rng: np.random.Generator) -> np.ndarray:
        """Noisy copy of a clean (H, W) depth image in metres; float32, 0 = invalid (as are NaN, inf,
        <= 0 and > 1e6 m on input). Pure; the same `rng` state gives the same image."""
        if not fx > 0:
            raise ValueError(f"DepthNoise.apply: focal length fx must be positive, got {fx}")
        depth = np.asarray(depth_m)
        if depth.ndim != 2:
            raise ValueError(f"DepthNoise.apply: depth must be an (H, W) image, got shape {depth.shape}")
        out = np.empty(depth.shape, np.float32)
        h, w = depth.shape
        step = max(1, _BLOCK_PX // max(w, 1))  # rows per block
        for r0 in range(0, h if w else 0, step):
            r1 = min(r0 + step, h)
            out[r0:r1] = self._noisy_rows(depth, r0, r1, fx, rng)
        if self.hole_rate > 0:
            out.flat[_bernoulli(rng, out.size, self.hole_rate)] = 0.0
        return out

    def _noisy_rows(
        self, depth: np.ndarray, r0: int, r1: int, fx: float, rng: np.random.Generator
    ) -> np.ndarray:
        """Rows r0:r1 of the noisy image, before holes."""
        h, w = depth.shape
        top, bottom = max(r0 - 1, 0), min(r1 + 1, h)
        rows = slice(r0 - top, r1 - top)
        near = depth[top:bottom].astype(np.float32)  # the rows and one neighbour row each side, a copy
        valid = (near > 0) & (near < _MAX_DEPTH_M)  # not NaN either
        near[~valid] = 0.0
        far = np.where(valid, near, np.float32(np.inf))  # invalid depth as 0 in `near`, inf in `far`
        out = near[rows].copy()
        if self.flying_pixel_rate > 0:
            edge, other = _jump_neighbours(near, far, self.edge_jump_m, rows)
            fly = rng.random(edge.size, np.float32) < self.flying_pixel_rate
            edge, other, here = edge[fly], other[fly], out.flat[edge[fly]]
            out.flat[edge] = here + rng.random(edge.size, np.float32) * (other - here)
        if self.subpixel > 0:
            out += rng.standard_normal(out.shape, dtype=np.float32) * self.sigma_m(out, fx)
        drop = (out < self.min_range_m) | (out > self.max_range_m) | (out <= 0)  # invalid depth is 0 here
        if self.max_incidence_deg < 90:
            drop |= _grazing(near, far, fx, (w - 1) / 2, (h - 1) / 2 - top, self.max_incidence_deg)[rows]
        out[drop] = 0.0
        if self.depth_unit_m > 0:
            out = np.multiply(np.round(out / self.depth_unit_m), self.depth_unit_m, dtype=np.float64)
        return out


def _bernoulli(rng: np.random.Generator, n: int, p: float) -> np.ndarray:
    """Indices of the successes among `n` independent trials of probability `p`: a binomial count
    of distinct uniform indices, so the cost grows with the successes, not with `n`."""
    if p >= 1:
        return np.arange(n)
    return rng.choice(n, rng.binomial(n, p), replace=False)


def _jump_neighbours(
    depth: np.ndarray, far: np.ndarray, jump_m: float, rows: slice
) -> tuple[np.ndarray, np.ndarray]:
    """Valid pixels of `depth[rows]` (flat indices) whose valid 4-neighbour differing most from them
    does so by more than `jump_m`, and that neighbour's depth: the deepest or the nearest one, from a
    max and a min filter. `far` is `depth` with inf for invalid depth."""
    deepest = cv2.dilate(depth, _CROSS)[rows]  # invalid depth is 0, never the maximum around a valid one
    nearest = cv2.erode(far, _CROSS)[rows]
    depth = depth[rows]
    behind, before = deepest - depth, depth - nearest
    edge = np.flatnonzero((depth > 0) & (np.maximum(behind, before) > jump_m))
    deeper = behind.flat[edge] >= before.flat[edge]
    return edge, np.where(deeper, deepest.flat[edge], nearest.flat[edge])


def _smooth_gradient(far: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dz/du, dz/dv) at valid pixels of `far` (depth, inf where invalid): per pixel the one-sided
    difference to a valid neighbour of smaller magnitude, so a depth jump on one side does not bend
    the surface; inf where neither neighbour is valid. Meaningless at invalid pixels."""
    h, w = far.shape
    steps_u = np.full((h, w + 1), np.inf, np.float32)  # steps_u[:, j] = z[:, j] - z[:, j - 1]
    steps_v = np.full((h + 1, w), np.inf, np.float32)
    with np.errstate(invalid="ignore"):  # inf - inf between two invalid pixels
        np.subtract(far[:, 1:], far[:, :-1], out=steps_u[:, 1:-1])
        np.subtract(far[1:], far[:-1], out=steps_v[1:-1])
    return _smaller(steps_u[:, 1:], steps_u[:, :-1]), _smaller(steps_v[1:], steps_v[:-1])


def _smaller(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """The step of smaller magnitude, forward on ties."""
    smaller = backward.copy()
    np.copyto(smaller, forward, where=np.abs(forward) <= np.abs(backward))
    return smaller


def _grazing(
    depth: np.ndarray, far: np.ndarray, fx: float, cx: float, cy: float, max_deg: float
) -> np.ndarray:
    """Pixels whose view ray meets the surface more than `max_deg` from its normal, for principal
    point (`cx`, `cy`) in this array's pixels. False where the normal is undefined; meaningless at
    invalid pixels (`depth` 0, `far` inf).

    For P = z (x, y, 1) with x = (u - cx) / fx, y = (v - cy) / fx, the normal dP/du x dP/dv is
    proportional to n = (-z_u, -z_v, x z_u + y z_v + z / fx), and n . (x, y, 1) = z / fx, so the
    angle exceeds `max_deg` where (z / fx)^2 < cos^2(max_deg) |n|^2 |(x, y, 1)|^2.
    Assumes square pixels, enough for a noise model.
    """
    h, w = depth.shape
    x = (np.arange(w, dtype=np.float32) - cx) / fx
    y = (np.arange(h, dtype=np.float32) - cy) / fx
    cos_sq = math.cos(math.radians(max_deg)) ** 2
    ray_sq = (cos_sq * x * x)[None, :] + (cos_sq * (y * y + 1))[:, None]  # cos^2 |(x, y, 1)|^2
    z_u, z_v = _smooth_gradient(far)
    z_f = depth / np.float32(fx)
    with np.errstate(invalid="ignore"):  # inf gradients (undefined normals) are masked out below
        n_z = x[None, :] * z_u + y[:, None] * z_v + z_f
        grazing = z_f * z_f < (z_u * z_u + z_v * z_v + n_z * n_z) * ray_sq
    return grazing & np.isfinite(z_u) & np.isfinite(z_v)
