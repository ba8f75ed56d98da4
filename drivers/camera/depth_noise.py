"""A depth-noise model resembling an Intel RealSense D415 (active IR stereo), for simulated depth.

Each effect is switchable: a zero sigma or rate, `depth_unit_m=0`, `min_range_m=0`, `max_range_m=inf`
or `max_incidence_deg=90` turns it off. The D415's minimum range is about 0.45 m at 1280x720 and less
at lower resolutions (about 0.3 m at 640x480, the default here) or with a disparity shift.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
        """Noisy copy of a clean (H, W) depth image in metres; float32, 0 = invalid. Pure."""
        if not fx > 0:
            raise ValueError(f"DepthNoise.apply: focal length fx must be positive, got {fx}")
        clean = np.asarray(depth_m, np.float64)
        if clean.ndim != 2:
            raise ValueError(f"DepthNoise.apply: depth must be an (H, W) image, got shape {clean.shape}")
        clean = np.where(np.isfinite(clean) & (clean > 0), clean, 0.0)
        valid = clean > 0
        out = clean.copy()

        if self.flying_pixel_rate > 0:
            other = _largest_jump_neighbour(clean)
            edge = valid & (np.abs(other - clean) > self.edge_jump_m)
            fly = edge & (rng.random(clean.shape) < self.flying_pixel_rate)
            u = rng.random(clean.shape)
            out = np.where(fly, clean + u * (other - clean), out)
        if self.subpixel > 0:
            out = out + rng.standard_normal(clean.shape) * self.sigma_m(out, fx)
        drop = ~valid
        if self.max_incidence_deg < 90:
            drop |= _incidence_deg(clean, fx) > self.max_incidence_deg
        if self.hole_rate > 0:
            drop |= rng.random(clean.shape) < self.hole_rate
        drop |= (out < self.min_range_m) | (out > self.max_range_m) | (out <= 0)
        if self.depth_unit_m > 0:
            out = np.round(out / self.depth_unit_m) * self.depth_unit_m
        return np.where(drop, 0.0, out).astype(np.float32)


def _neighbours(depth: np.ndarray) -> list[np.ndarray]:
    """The 4-neighbour images (edge-replicated at the border)."""
    p = np.pad(depth, 1, mode="edge")
    return [p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]]


def _largest_jump_neighbour(depth: np.ndarray) -> np.ndarray:
    """For each pixel, the valid 4-neighbour depth that differs most from it (itself if none)."""
    best = depth.copy()
    for nb in _neighbours(depth):
        take = (nb > 0) & (np.abs(nb - depth) > np.abs(best - depth))
        best = np.where(take, nb, best)
    return best


def _smooth_gradient(depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dz/du, dz/dv): per pixel the smaller one-sided difference to a valid neighbour, so a depth
    jump on one side does not bend the surface; inf where neither neighbour is valid."""
    p = np.pad(depth, 1)
    grads = []
    for before, after in ((p[1:-1, :-2], p[1:-1, 2:]), (p[:-2, 1:-1], p[2:, 1:-1])):
        forward = np.where(after > 0, after - depth, np.inf)
        backward = np.where(before > 0, depth - before, np.inf)
        grads.append(np.where(np.abs(forward) <= np.abs(backward), forward, backward))
    return grads[0], grads[1]


def _incidence_deg(depth: np.ndarray, fx: float) -> np.ndarray:
    """Angle (deg) between each pixel's view ray and its surface normal; 0 where undefined.

    For P = z (x, y, 1) with x = (u - cx) / fx, y = (v - cy) / fx, the normal dP/du x dP/dv is
    proportional to n = (-z_u, -z_v, x z_u + y z_v + z / fx), and n . (x, y, 1) = z / fx.
    Assumes a centred principal point and square pixels, enough for a noise model.
    """
    h, w = depth.shape
    x = ((np.arange(w) - (w - 1) / 2) / fx)[None, :]
    y = ((np.arange(h) - (h - 1) / 2) / fx)[:, None]
    z_u, z_v = _smooth_gradient(depth)
    defined = (depth > 0) & np.isfinite(z_u) & np.isfinite(z_v)
    z_u, z_v = np.where(defined, z_u, 0.0), np.where(defined, z_v, 0.0)
    n_z = x * z_u + y * z_v + depth / fx
    norm = np.sqrt((z_u * z_u + z_v * z_v + n_z * n_z) * (x * x + y * y + 1.0))
    cos = (depth / fx) / np.where(norm > 0, norm, 1.0)
    return np.where(defined, np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))), 0.0)
