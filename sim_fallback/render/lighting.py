"""Light and the colour camera: a room's lights (a ceiling lamp casting shadows, two weaker fills, ambient),
Lambert + Blinn-Phong shading, auto exposure and sensor noise.

Radiometry is linear RGB in arbitrary units; the camera scales it by its exposure, adds shot and read noise and
encodes sRGB to 8 bits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from sim_fallback.render.rays import Surface
from sim_fallback.render.view import Light

EXPOSURE_KEY = 0.18  # auto exposure brings the image's mean linear luminance here,
HIGHLIGHTS = (0.98, 0.9)  # unless that puts this quantile of it above this fraction of full scale
EXPOSURE_RATE = 0.1  # fraction of the way (in stops) to the new exposure per frame: it settles over frames
METERING_STEP = 8  # the exposure meters every 8th pixel of every 8th row
SHOT_NOISE = 2e-4  # variance per unit of exposed linear signal
READ_NOISE = 0.003  # standard deviation, linear
NOISE_POOL = 2  # colour noise drawn once per camera, this many images' worth, read at a random offset per frame
BACKGROUND_RGB = (0.05, 0.05, 0.05)  # empty space (linear)
LAMP_HEIGHT_M = 2.4
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
_LEVELS = 4096  # linear levels the exposed signal is quantised to before sRGB encoding


@dataclass(frozen=True)
class Lighting:
    """`lamp` the main light, which casts shadows, and its `lamp_rgb` intensity at 1 m; `fills` unit directions
    toward two distant lights without shadows and their `fill_rgb`; `ambient_rgb`."""

    lamp: Light
    lamp_rgb: tuple[float, float, float]
    fills: tuple[tuple[float, float, float], ...]
    fill_rgb: tuple[tuple[float, float, float], ...]
    ambient_rgb: tuple[float, float, float]

    @classmethod
    def room(cls, T_base_camera: np.ndarray, seed: int = 0) -> Lighting:
        """A room's light for a camera looking at a scene: a ceiling lamp LAMP_HEIGHT_M up, above a point 1.2 m in
        front of the camera (shifted up to 1 m sideways, seeded), warm or cool; fills from above either side."""
        rng = np.random.default_rng([seed, 7])
        ahead = T_base_camera[:3, 3] + 1.2 * T_base_camera[:3, 2]
        lamp = (float(ahead[0] + rng.uniform(-1, 1)), float(ahead[1] + rng.uniform(-1, 1)), LAMP_HEIGHT_M)
        warmth = rng.uniform(-0.08, 0.08)
        fills = []
        for side in (-1, 1):
            azimuth = math.atan2(T_base_camera[1, 2], T_base_camera[0, 2]) + side * rng.uniform(0.8, 1.6) + math.pi
            elevation = rng.uniform(0.5, 1.1)
            fills.append((math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                          math.sin(elevation)))
        strength = rng.uniform(0.2, 0.45, 2)
        return cls(Light(lamp, (0.0, 0.0, -1.0)), (5.0 * (1 + warmth), 5.0, 5.0 * (1 - warmth)), tuple(fills),
                   tuple((float(s), float(s), float(s) * 1.05) for s in strength), (0.22, 0.22, 0.24))

    def shade(self, s: Surface, rgb: np.ndarray, gloss: np.ndarray, lit: np.ndarray) -> np.ndarray:
        """(3, n) linear radiance toward the camera: diffuse from the lamp (where `lit[0]`), the fills and the
        ambient, and the lamp's specular highlight."""
        nx, ny, nz = s.normal
        lx, ly, lz = (np.float32(c) - p for c, p in zip(self.lamp.position, s.point, strict=True))
        r2 = lx * lx + ly * ly + lz * lz
        inv_r = 1.0 / np.sqrt(r2)
        cosine = np.maximum((nx * lx + ny * ly + nz * lz) * inv_r, 0.0) * lit[0]
        lamp = cosine / r2
        fills = [np.maximum(nx * dx + ny * dy + nz * dz, 0.0) for dx, dy, dz in self.fills]
        vx, vy, vz = s.view  # Blinn-Phong: the half vector between the lamp and the view
        hx, hy, hz = lx * inv_r + vx, ly * inv_r + vy, lz * inv_r + vz
        cos_half = np.maximum(nx * hx + ny * hy + nz * hz, 1e-6) / np.sqrt(hx * hx + hy * hy + hz * hz + 1e-12)
        shininess = 8.0 + 400.0 * gloss * gloss
        highlight = np.exp(shininess * np.log(cos_half)) * (0.03 + 0.6 * gloss) * (shininess + 8.0) / (
            8.0 * math.pi) * lamp
        out = np.empty((3, len(nx)), np.float32)
        for c in range(3):
            irradiance = self.ambient_rgb[c] + self.lamp_rgb[c] * lamp
            for fill, colour in zip(fills, self.fill_rgb, strict=True):
                irradiance += colour[c] * fill
            out[c] = rgb[c] * irradiance + self.lamp_rgb[c] * highlight
        return out


class Exposure:
    """The colour camera's auto exposure (metering the mean luminance, sparing the highlights, settling over
    frames) and sensor noise, with a seeded exposure bias (+-0.3 EV) and white balance error (+-3 %)."""

    def __init__(self, shape: tuple[int, int], seed: int) -> None:
        rng = np.random.default_rng([seed, 11])
        self.shape = shape
        self._bias = 2.0 ** rng.uniform(-0.3, 0.3)
        self._balance = (1.0 + rng.uniform(-0.03, 0.03, 3)).astype(np.float32)
        self._scale: float | None = None
        self._pool = rng.standard_normal(NOISE_POOL * shape[0] * shape[1] * 3, dtype=np.float32)
        x = (np.arange(_LEVELS, dtype=np.float64) + 0.5) / _LEVELS
        srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
        self._encode = np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8)

    def image(self, radiance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(H, W, 3) uint8 sRGB of the (3, H * W) linear radiance."""
        metered = _LUMA @ radiance.reshape(3, *self.shape)[:, ::METERING_STEP, ::METERING_STEP].reshape(3, -1)
        highlight = float(np.quantile(metered, HIGHLIGHTS[0]))
        target = self._bias * min(EXPOSURE_KEY / max(float(metered.mean()), 1e-6),
                                  HIGHLIGHTS[1] / max(highlight, 1e-6))
        self._scale = target if self._scale is None else self._scale * (target / self._scale) ** EXPOSURE_RATE
        level = radiance * (self._scale * _LEVELS * self._balance).astype(np.float32)[:, None]  # 1/4096 of full
        start = int(rng.integers(0, len(self._pool) - level.size + 1))
        sigma = np.sqrt(np.maximum(level, 0.0) * np.float32(SHOT_NOISE * _LEVELS) + np.float32(
            (READ_NOISE * _LEVELS) ** 2))
        level += sigma * self._pool[start:start + level.size].reshape(level.shape)
        np.clip(level, 0, _LEVELS - 1, out=level)
        codes = level.astype(np.uint16)
        return cv2.merge([self._encode.take(codes[c]).reshape(self.shape) for c in range(3)])
