"""Active stereo as a RealSense D415 measures depth, the way SAPIEN / ManiSkill simulate it: the two infrared
cameras (55 mm apart) see the scene lit by the projector's dot pattern and the room's ambient infrared, and
OpenCV's semi-global matcher finds each left pixel's disparity d in the right image; Z = f B / d.

The left infrared camera is the colour camera (depth comes aligned to colour), the right one sits `baseline_m` to
its right (camera x) and the projector between them. The artefacts are the matcher's: no match at the left edge
(a band about f B / Z wide, the points the right camera cannot see), none where the right camera or the projector
cannot see the point (beside depth edges), edges widened by the matching window, holes where the dots return too
little light over the sensor's noise (dark or glossy surfaces, far away) or where a surface is thinner than the
window, and noise that grows with Z^2 and is correlated over the window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from sim_fallback.render.rays import Surface
from sim_fallback.render.view import Light, Seen

DOT_SPACING_PX = 3.2  # mean distance between the projector's dots, in image pixels at the camera's focal length
DOT_SIGMA_PX = 0.6  # a dot's Gaussian radius, same units
PATTERN_OVERSAMPLING = 2  # pattern texels per image pixel
IR_MEAN_LEVEL = 40.0  # the infrared auto exposure brings the left image's mean here (8-bit levels)
PATTERN_MARGIN = 0.2  # the projector's field of view exceeds the camera's by this fraction of it on each side


@lru_cache(maxsize=8)
def dot_pattern(width: int, height: int, seed: int = 0) -> np.ndarray:
    """The projector's pattern: random dots, (height, width) float32 in 0-1, at PATTERN_OVERSAMPLING texels per
    pixel of a camera with the same field of view."""
    rng = np.random.default_rng([seed, 5])
    s = PATTERN_OVERSAMPLING
    count = int(width * height / DOT_SPACING_PX ** 2)
    image = np.zeros((height * s, width * s), np.float32)
    rows, cols = rng.integers(0, height * s, count), rng.integers(0, width * s, count)
    np.add.at(image, (rows, cols), rng.uniform(0.6, 1.0, count).astype(np.float32))
    image = cv2.GaussianBlur(image, (0, 0), DOT_SIGMA_PX * s)
    return image / image.max()


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """`image` at texel coordinates (x, y) (texel centres at integers), clamped at the border."""
    h, w = image.shape
    x = np.clip(x, 0, w - 1.001)
    y = np.clip(y, 0, h - 1.001)
    x0, y0 = x.astype(np.int64), y.astype(np.int64)
    fx, fy = x - x0, y - y0
    flat = image.ravel()
    i = y0 * w + x0
    top = flat.take(i) * (1 - fx) + flat.take(i + 1) * fx
    bottom = flat.take(i + w) * (1 - fx) + flat.take(i + w + 1) * fx
    return top * (1 - fy) + bottom * fy


@dataclass(frozen=True)
class ActiveStereo:
    """The D415's stereo depth. `baseline_m` between the infrared cameras; `min_range_m` sets the disparity search
    (f B / min range, rounded up to 16); `block_px` the matching window; `projector_w` the projector's power
    (irradiance at 1 m on a surface facing it, in the units of the `ambient_ir`); `gain_cap` the most the infrared
    auto exposure (which brings the image's mean to IR_MEAN_LEVEL: near bright surfaces saturate) amplifies;
    `shot_noise` / `read_noise` the infrared sensor's (8-bit levels); the matcher's filters `uniqueness`,
    `speckle_px` and `texture_snr` (the least ratio of the left image's contrast over the window to its noise
    there for a match to be trusted, as the D415's texture threshold does); `depth_unit_m` the depth's
    quantisation."""

    baseline_m: float = 0.055
    min_range_m: float = 0.3
    max_range_m: float = 10.0
    block_px: int = 5
    projector_w: float = 1.0
    ambient_ir: float = 0.04
    gain_cap: float = 4000.0
    shot_noise: float = 0.07
    read_noise: float = 1.5
    uniqueness: int = 10
    speckle_px: int = 100
    texture_snr: float = 1.0
    depth_unit_m: float = 0.001
    seed: int = 0

    def disparities(self, fx: float) -> int:
        """The matcher's disparity search range (a multiple of 16) for focal length `fx`."""
        return 16 * math.ceil(fx * self.baseline_m / self.min_range_m / 16)

    def projector(self, T_base_camera: np.ndarray) -> Light:
        """The projector: midway between the cameras, facing along the camera's z."""
        return Light(tuple(T_base_camera[:3, 3] + T_base_camera[:3, 0] * self.baseline_m / 2),
                     tuple(T_base_camera[:3, 2]))

    def right(self, T_base_camera: np.ndarray) -> np.ndarray:
        """Pose of the right infrared camera."""
        T = T_base_camera.copy()
        T[:3, 3] += T[:3, 0] * self.baseline_m
        return T

    def shader(self, T_base_camera: np.ndarray, intrinsics, light_index: int):
        """The infrared radiance (1, n) of a view's hits: the dots where the projector of the camera at
        `T_base_camera` (light `light_index`) reaches the surface, plus ambient, times the infrared return; a glossy
        surface's highlight of the projector."""
        margin = PATTERN_MARGIN
        pattern = dot_pattern(round(intrinsics.width * (1 + 2 * margin)), round(intrinsics.height * (1 + 2 * margin)),
                              self.seed)
        R = T_base_camera[:3, :3].astype(np.float32)
        origin = np.asarray(self.projector(T_base_camera).position, np.float32)
        s_ = PATTERN_OVERSAMPLING
        fx, fy = np.float32(intrinsics.fx * s_), np.float32(intrinsics.fy * s_)
        cx = np.float32((intrinsics.cx + 0.5 + margin * intrinsics.width) * s_)
        cy = np.float32((intrinsics.cy + 0.5 + margin * intrinsics.height) * s_)

        def shade(s: Surface, rgb: np.ndarray, gloss: np.ndarray, lit: np.ndarray) -> np.ndarray:
            q = R.T @ (s.point - origin[:, None])  # points in the projector's frame
            ahead = q[2] > 1e-3
            z = np.where(ahead, q[2], 1.0)
            dots = _bilinear(pattern, fx * q[0] / z + cx - 0.5, fy * q[1] / z + cy - 0.5) * ahead * lit[light_index]
            lx, ly, lz = -q[0], -q[1], -q[2]  # toward the projector, in its frame; the normal likewise
            n = R.T @ s.normal
            r2 = lx * lx + ly * ly + lz * lz
            cosine = np.maximum((n[0] * lx + n[1] * ly + n[2] * lz) / np.sqrt(r2), 0.0)
            irradiance = self.projector_w * dots * cosine / r2
            albedo = rgb[0] * 0.2126 + rgb[1] * 0.7152 + rgb[2] * 0.0722
            v = R.T @ s.view  # a highlight where the projector's reflection meets the camera
            inv_r = 1.0 / np.sqrt(r2)
            h = np.stack([lx * inv_r + v[0], ly * inv_r + v[1], lz * inv_r + v[2]])
            cos_half = np.maximum(np.einsum("kn,kn->n", n, h), 1e-6) / np.sqrt(np.einsum("kn,kn->n", h, h) + 1e-12)
            shininess = 8.0 + 400.0 * gloss * gloss
            highlight = np.exp(shininess * np.log(cos_half)) * gloss * (shininess + 8.0) / (8.0 * math.pi)
            return (albedo * (1.0 - gloss) * (irradiance + self.ambient_ir) + highlight * irradiance)[None, :]

        return shade

    def measure(self, left: Seen, right: Seen, T_base_camera: np.ndarray, intrinsics, rng: np.random.Generator
                ) -> np.ndarray:
        """Depth (H, W) float32 metres (0 = no depth) from the left and right views, each seen with the lamp and
        the projector (light 1) as its lights."""
        shape = (intrinsics.height, intrinsics.width)
        images = []
        shader = self.shader(T_base_camera, intrinsics, 1)
        for name, seen in (("ir left", left), ("ir right", right)):
            images.append(seen.image(name, shader)[0].reshape(shape))
        gain = min(self.gain_cap, IR_MEAN_LEVEL / max(float(images[0].mean()), 1e-9))  # auto exposure
        noisy = []
        for image in images:
            level = image * gain
            level += rng.standard_normal(shape, dtype=np.float32) * np.sqrt(
                self.shot_noise * level + self.read_noise ** 2)
            noisy.append(np.clip(np.rint(level), 0, 255).astype(np.uint8))
        return self.match(noisy[0], noisy[1], intrinsics.fx)

    def _textured(self, image: np.ndarray) -> np.ndarray:
        """Pixels whose matching window shows more contrast than the sensor's noise explains: variance over the
        window above (1 + texture_snr^2) times the noise variance at the window's mean level."""
        x = image.astype(np.float32)
        window = (self.block_px, self.block_px)
        mean = cv2.boxFilter(x, -1, window)
        variance = cv2.boxFilter(x * x, -1, window) - mean * mean
        noise = self.read_noise ** 2 + self.shot_noise * mean + 1.0 / 12  # + the 8-bit rounding
        return variance > (1.0 + self.texture_snr ** 2) * noise

    def match(self, left: np.ndarray, right: np.ndarray, fx: float) -> np.ndarray:
        """Depth (metres, 0 = none) of the left 8-bit image from the rectified pair: SGBM with the images padded on
        the left, so that the matcher's own blind band falls in the padding and the band the right camera cannot
        see is left to the matching."""
        n = self.disparities(fx)
        b = self.block_px
        sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=n, blockSize=b, P1=8 * b * b, P2=32 * b * b,
                                     disp12MaxDiff=1, uniquenessRatio=self.uniqueness,
                                     speckleWindowSize=self.speckle_px, speckleRange=2,
                                     mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
        pad = ((0, 0), (n, 0))
        disparity = sgbm.compute(np.pad(left, pad), np.pad(right, pad))[:, n:].astype(np.float32) / 16.0
        disparity = refine(left, right, disparity, b)
        disparity[~self._textured(left)] = 0.0
        with np.errstate(divide="ignore"):
            depth = np.where(disparity > 0, np.float32(fx * self.baseline_m) / disparity, 0.0)
        depth[(depth < self.min_range_m) | (depth > self.max_range_m)] = 0.0
        if self.depth_unit_m > 0:
            depth = np.round(depth / self.depth_unit_m) * self.depth_unit_m
        return depth.astype(np.float32)


def refine(left: np.ndarray, right: np.ndarray, disparity: np.ndarray, block_px: int) -> np.ndarray:
    """Sub-pixel disparities: one Lucas-Kanade step over the matching window from the matcher's disparity (OpenCV's
    own sub-pixel fit is drawn toward whole pixels), the right image interpolated linearly. Invalid (<= 0)
    disparities stay as they are."""
    h, w = left.shape
    L, R = left.astype(np.float32), right.astype(np.float32)
    gradient = np.zeros_like(R)
    gradient[:, 1:-1] = (R[:, 2:] - R[:, :-2]) / 2
    x = np.clip(np.arange(w, dtype=np.float32)[None, :] - np.maximum(disparity, 0), 0, w - 1.001)
    x0 = x.astype(np.int64)
    frac = x - x0
    index = np.arange(h)[:, None] * w + x0
    shifted = R.ravel().take(index) * (1 - frac) + R.ravel().take(index + 1) * frac
    slope = gradient.ravel().take(index) * (1 - frac) + gradient.ravel().take(index + 1) * frac
    valid = (disparity > 0).astype(np.float32)
    num = cv2.boxFilter((shifted - L) * slope * valid, -1, (block_px, block_px), normalize=False)
    den = cv2.boxFilter(slope * slope * valid, -1, (block_px, block_px), normalize=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.clip(np.where(den > 0, num / den, 0.0), -0.5, 0.5)
    return np.where(disparity > 0, disparity + step, disparity).astype(np.float32)


