"""A depth model of an Intel RealSense D415 (active infrared stereo, left camera the reference, the right one
`baseline_m` to its right), for simulated depth: the artefacts of its stereo matching computed from exact depth.

Effects, each switchable (a zero sigma, rate, width or threshold, `stereo_shadows=False`, `depth_unit_m=0`,
`min_range_m=0`, `max_range_m=inf` or `max_incidence_deg=90` turns it off):
- axial noise sigma_z = z^2 * subpixel / (fx * baseline), correlated over a `correlation_px` square (the
  matching window averages it); quantisation to `depth_unit_m`;
- `stereo_shadows`: no depth where the right camera cannot see the point: the band at the left edge (about
  fx * baseline / z wide) and the shadows beside depth edges, on the far side to the left of a nearer surface,
  both `stereo_margin_px` wider (where the matching window reaches them);
- `edge_widening_px`: nearer surfaces spread this far over farther ones (the matching window straddles the edge);
- `thin_px`: no depth on surfaces narrower than this (across rows or columns) standing out of their background;
- `min_return`, `min_relative_return`: no depth where the infrared return (0-1, given per pixel as `reflectance`)
  over z^2 (m) is below `min_return`, or below `min_relative_return` times the image's mean (the infrared auto
  exposure is set for it): dark and glossy surfaces, far away or beside bright ones, lose the projector's dots;
  the boundary is patchy;
- random holes, dropout at grazing incidence, flying pixels at depth edges, range limits.
The D415's minimum range is about 0.45 m at 1280x720 and less at lower resolutions (about 0.3 m at 640x480, the
default here) or with a disparity shift. docs/simulation.md gives how the parameters were set.

Speed (a 640x480 frame in about 5 ms on one core): the image is processed in float32 (the output
type; its rounding is far below the noise) and in blocks of rows whose temporaries stay in cache,
and flying pixels and holes draw random numbers only for the pixels concerned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

_MAX_DEPTH_M = 1e6  # larger (or inf) is no depth, and squares of smaller ones stay finite in float32
_BLOCK_PX = 32768  # pixels per block of rows: small temporaries stay in cache and are reused
_PATCH_SPREAD = math.exp(1.5)  # dark-surface losses reach this factor above `min_return` (3 sigma)
_CROSS = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], np.uint8)  # the 4 neighbours, not the pixel itself


@dataclass(frozen=True)
class DepthNoise:
    """Stereo depth noise (see the module docstring).

    axial sigma_z = z^2 * subpixel / (fx * baseline_m) (Intel's RMS-error formula); quantisation to
    `depth_unit_m`; random holes at `hole_rate`; dropout where the view ray meets the surface more
    than `max_incidence_deg` from its normal; flying pixels: a pixel next to a depth jump larger than
    `edge_jump_m` gets, with probability `flying_pixel_rate`, a value between the two sides; depths
    outside [`min_range_m`, `max_range_m`] read 0. Correlated noise, stereo shadows, widened edges, thin
    surfaces and dark surfaces as in the module docstring.
    """

    baseline_m: float = 0.055
    subpixel: float = 0.0
    correlation_px: int = 0
    depth_unit_m: float = 0.0
    hole_rate: float = 0.0
    max_incidence_deg: float = 90.0
    flying_pixel_rate: float = 0.0
    edge_jump_m: float = 0.02
    min_range_m: float = 0.0
    max_range_m: float = math.inf
    stereo_shadows: bool = False
    stereo_margin_px: int = 0
    edge_widening_px: int = 0
    thin_px: int = 0
    min_return: float = 0.0
    min_relative_return: float = 0.0

    @classmethod
    def none(cls) -> DepthNoise:
        """Perfect depth (every effect off)."""
        return cls()

    @classmethod
    def d415(cls) -> DepthNoise:
        """A D415 at 640x480, calibrated against the active-stereo simulation (sim_fallback.render.stereo) and
        the datasheet (docs/simulation.md): disparity noise 0.085 px over a 5 px window, stereo
        shadows and the left band 1 px wider, edges widened 1 px, surfaces up to 3 px wide lost, dots lost below
        an infrared return (over z^2) of 0.005 or of 3.5 % of the image's mean; 1 mm units, 0.3-10 m
        range."""
        return cls(
            subpixel=0.085,
            correlation_px=5,
            depth_unit_m=0.001,
            max_incidence_deg=80.0,
            flying_pixel_rate=0.5,
            min_range_m=0.3,
            max_range_m=10.0,
            stereo_shadows=True,
            stereo_margin_px=1,
            edge_widening_px=1,
            thin_px=3,
            min_return=0.005,
            min_relative_return=0.035,
        )

    def sigma_m(self, depth_m: np.ndarray | float, fx: float) -> np.ndarray:
        """Axial noise standard deviation (m) at `depth_m` for focal length `fx` (px)."""
        return np.square(depth_m) * self.subpixel / (fx * self.baseline_m)

    def apply(self, depth_m: np.ndarray, fx: float, rng: np.random.Generator,
              reflectance: np.ndarray | None = None) -> np.ndarray:
        """Noisy copy of a clean (H, W) depth image in metres; float32, 0 = invalid (as are NaN, inf,
        <= 0 and > 1e6 m on input). `reflectance` (H, W): each pixel's infrared return in 0-1 (needed by
        `min_return`; without it dark surfaces keep their depth). Pure; the same `rng` state gives the
        same image."""
        if not fx > 0:
            raise ValueError(f"DepthNoise.apply: focal length fx must be positive, got {fx}")
        depth = np.asarray(depth_m)
        if depth.ndim != 2:
            raise ValueError(f"DepthNoise.apply: depth must be an (H, W) image, got shape {depth.shape}")
        h, w = depth.shape
        lost = self._stereo_losses(depth, fx, rng, reflectance) if h and w else None
        if self.edge_widening_px > 0 and h and w:
            depth = _widen(_clean(depth), self.edge_widening_px, self.edge_jump_m)
        field = None
        if self.subpixel > 0 and self.correlation_px > 1 and h and w:
            field = _window_noise(rng, depth.shape, self.correlation_px)
        out = np.empty(depth.shape, np.float32)
        step = max(1, _BLOCK_PX // max(w, 1))  # rows per block
        for r0 in range(0, h if w else 0, step):
            r1 = min(r0 + step, h)
            out[r0:r1] = self._noisy_rows(depth, r0, r1, fx, rng, None if field is None else field[r0:r1])
        if lost is not None:
            out[lost] = 0.0
        if self.hole_rate > 0:
            out.flat[_bernoulli(rng, out.size, self.hole_rate)] = 0.0
        return out

    def _stereo_losses(self, depth: np.ndarray, fx: float, rng: np.random.Generator,
                       reflectance: np.ndarray | None) -> np.ndarray | None:
        """Pixels the stereo matching loses: unseen by the right camera, on thin or on dark surfaces (None: none
        of these effects is on)."""
        dark = (self.min_return > 0 or self.min_relative_return > 0) and reflectance is not None
        if not (self.stereo_shadows or self.thin_px > 0 or dark):
            return None
        z = _clean(depth)
        lost = np.zeros(z.shape, bool)
        if self.stereo_shadows:
            lost |= _unseen_by_right(z, fx * self.baseline_m, self.stereo_margin_px)
        if self.thin_px > 0:
            lost |= _thin(z, self.thin_px, self.edge_jump_m)
        if dark:
            with np.errstate(divide="ignore", invalid="ignore"):
                signal = np.where(z > 0, np.asarray(reflectance, np.float32) / (z * z), 0.0)
            seen = signal[::4, ::4][z[::4, ::4] > 0]
            floor = max(self.min_return, self.min_relative_return * float(seen.mean()) if seen.size else 0.0)
            maybe = (z > 0) & (signal < floor * _PATCH_SPREAD)
            if maybe.any():  # a patchy boundary, not a clean contour
                lost |= maybe & (signal < floor * np.exp(0.5 * _patches(rng, z.shape)))
        return lost

    def _noisy_rows(
        self, depth: np.ndarray, r0: int, r1: int, fx: float, rng: np.random.Generator,
        field: np.ndarray | None = None,
    ) -> np.ndarray:
        """Rows r0:r1 of the noisy image, before holes; `field` (their unit-variance noise) or white noise."""
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
            unit = rng.standard_normal(out.shape, dtype=np.float32) if field is None else field
            out += unit * self.sigma_m(out, fx)
        truth = near[rows]
        drop = (out < self.min_range_m) | (out > self.max_range_m) | (out <= 0)  # invalid depth is 0 here
        drop |= (truth < self.min_range_m) | (truth > self.max_range_m)  # no disparity to find out there
        if self.max_incidence_deg < 90:
            drop |= _grazing(near, far, fx, (w - 1) / 2, (h - 1) / 2 - top, self.max_incidence_deg)[rows]
        out[drop] = 0.0
        if self.depth_unit_m > 0:
            out = np.multiply(np.round(out / self.depth_unit_m), self.depth_unit_m, dtype=np.float64)
        return out


def _clean(depth: np.ndarray) -> np.ndarray:
    """float32 copy with invalid depth (NaN, inf, <= 0, absurdly far) as 0."""
    z = np.asarray(depth, np.float32).copy()
    z[~((z > 0) & (z < _MAX_DEPTH_M))] = 0.0
    return z


def _unseen_by_right(z: np.ndarray, f_baseline: float, margin_px: int) -> np.ndarray:
    """Valid pixels of `z` the right camera cannot see, grown `margin_px` to the left. A left pixel u at disparity
    d = f B / z meets the right image at x = u - d: outside it when x < 0 (the left band); hidden when some pixel
    further right on its row lands at a smaller x (a nearer surface in between: the shadow beside an edge). Exact
    for what the left camera sees (rectified cameras: rows are epipolar lines)."""
    h, w = z.shape
    valid = z > 0
    with np.errstate(divide="ignore"):
        d = np.where(valid, np.float32(f_baseline) / z, 0.0).astype(np.float32)
    x = np.arange(w, dtype=np.float32)[None, :] - d
    nearest_right = np.full((h, w), np.inf, np.float32)
    nearest_right[:, :-1] = np.minimum.accumulate(x[:, ::-1], axis=1)[:, ::-1][:, 1:]
    unseen = ((x < margin_px) | (nearest_right < x - 0.01)).astype(np.uint8)
    if margin_px > 0:
        after = np.ones((1, margin_px + 1), np.uint8)  # a pixel up to margin_px left of an unseen one
        unseen = cv2.dilate(unseen, after, anchor=(0, 0))
    return valid & unseen.astype(bool)


def _widen(z: np.ndarray, radius_px: int, jump_m: float) -> np.ndarray:
    """Nearer surfaces spread `radius_px` over farther ones (and over missing depth): a pixel takes the nearest
    depth within the (2r + 1)^2 window when that is more than `jump_m` nearer."""
    far = np.where(z > 0, z, np.float32(np.inf))
    nearest = cv2.erode(far, np.ones((2 * radius_px + 1, 2 * radius_px + 1), np.uint8))
    with np.errstate(invalid="ignore"):  # inf - inf where nothing is near
        spread = (far - nearest > jump_m) & np.isfinite(nearest)
    return np.where(spread, nearest, z)


def _thin(z: np.ndarray, width_px: int, jump_m: float) -> np.ndarray:
    """Valid pixels with something more than `jump_m` deeper (or no depth) within `width_px` on both sides, along
    the row or along the column: surfaces at most about `width_px` wide."""
    far = np.where(z > 0, z, np.float32(np.inf))
    k = width_px
    side = np.ones((1, k + 1), np.uint8)
    side[0, k] = 0  # the pixel's k neighbours before it (after it: anchored at the other end, flipped)
    thin = np.zeros(z.shape, bool)
    for kernel in (side, side.T):
        before = cv2.dilate(far, kernel, anchor=(k, 0) if kernel.shape[0] == 1 else (0, k),
                            borderType=cv2.BORDER_REPLICATE)
        after = cv2.dilate(far, kernel[::-1, ::-1].copy(), anchor=(0, 0), borderType=cv2.BORDER_REPLICATE)
        with np.errstate(invalid="ignore"):  # inf - inf between pixels without depth
            thin |= (np.minimum(before, after) - far) > jump_m
    return thin & (z > 0)


def _patches(rng: np.random.Generator, shape: tuple[int, int], cell_px: int = 8) -> np.ndarray:
    """A smooth unit-scale random field varying over about `cell_px` (cells of random values, interpolated)."""
    h, w = shape
    cells = rng.standard_normal((h // cell_px + 2, w // cell_px + 2), dtype=np.float32)
    return cv2.resize(cells, (w, h), interpolation=cv2.INTER_LINEAR)


@lru_cache(maxsize=4)
def _noise_pool(shape: tuple[int, int], window_px: int) -> np.ndarray:
    """Unit-variance white noise averaged over a `window_px` square (the noise a matching window leaves), two
    images' worth, flat; drawn once: each image reads it from a random offset."""
    h, w = shape
    white = np.random.default_rng(0).standard_normal((2 * h, w), dtype=np.float32)
    field = cv2.boxFilter(white, -1, (window_px, window_px), borderType=cv2.BORDER_REFLECT) * np.float32(window_px)
    return field.ravel()


def _window_noise(rng: np.random.Generator, shape: tuple[int, int], window_px: int) -> np.ndarray:
    """Correlated unit-variance noise for one image (see `_noise_pool`)."""
    pool = _noise_pool(shape, window_px)
    n = shape[0] * shape[1]
    start = int(rng.integers(0, len(pool) - n + 1))
    return pool[start:start + n].reshape(shape)


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
