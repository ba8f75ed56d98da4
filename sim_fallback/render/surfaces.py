"""How surfaces look: base colour (linear RGB) and gloss per pixel, from the finishes of links (wood, laminate,
painted, metal: procedural patterns laid triplanar in the link's frame, so boxes need no texture coordinates) and,
for links without a finish, their URDF / MTL colours and textures (OBJ + MTL map_Kd with UVs), painted.

Everything that does not change with the view is a per-triangle table (colour, gloss, pattern, texel coordinates
of the corners); a frame looks the tables up at each pixel's triangle and samples one pattern atlas.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache

import cv2
import numpy as np

from sim_fallback.furniture import Finish
from sim_fallback.render.meshes import srgb_to_linear, texture_image
from sim_fallback.render.rays import Surface
from sim_fallback.render.scene import Triangles

TILE_PX = 256  # a pattern tile's side in texels (a power of two: texel coordinates wrap with a mask)
TEXELS_PER_M = 400.0  # 2.5 mm texels: a tile repeats every 0.64 m
UNFINISHED = Finish()  # links without a finish: painted, in their own colours
# (grain contrast, fine-noise contrast) of each finish kind's pattern
_CONTRAST = {"wood": (0.22, 0.04), "laminate": (0.035, 0.025), "painted": (0.0, 0.012), "metal": (0.06, 0.05)}
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


def _value_noise(rng: np.random.Generator, cells: tuple[int, int]) -> np.ndarray:
    """Smooth noise in about [-1, 1] on a TILE_PX tile from a (rows, cols) grid of random values, wrapping."""
    grid = rng.uniform(-1.0, 1.0, cells).astype(np.float32)
    big = cv2.resize(np.tile(grid, (3, 3)), (3 * TILE_PX, 3 * TILE_PX), interpolation=cv2.INTER_CUBIC)
    return big[TILE_PX:2 * TILE_PX, TILE_PX:2 * TILE_PX]


@lru_cache(maxsize=128)
def pattern(kind: str, seed: int) -> np.ndarray:
    """A TILE_PX x TILE_PX brightness pattern (mean about 1) of a finish kind; its grain runs along axis 1 (u)."""
    rng = np.random.default_rng([seed, sum(map(ord, kind))])
    grain, fine = _CONTRAST[kind]
    out = np.ones((TILE_PX, TILE_PX), np.float32)
    if kind == "wood":  # growth rings cut lengthwise: bands across v, warped along u
        v = np.arange(TILE_PX, dtype=np.float32)[:, None] / TILE_PX
        warp = _value_noise(rng, (8, 3)) * 1.5 + _value_noise(rng, (32, 6)) * 0.3
        rings = 0.5 + 0.5 * np.sin(2 * np.pi * (v * rng.integers(10, 16) + warp))
        out += grain * (rings ** 3 - 0.3)
    elif kind == "laminate":  # a printed pattern: faint streaks along u
        out += grain * _value_noise(rng, (48, 4))
    elif kind == "metal":  # brushed: long thin streaks along u
        out += grain * _value_noise(rng, (TILE_PX, 6))
    out += fine * _value_noise(rng, (TILE_PX // 2, TILE_PX // 2)) + fine * 0.5 * _value_noise(rng, (16, 16))
    return out


def _corner_table(values: np.ndarray) -> np.ndarray:
    """(n, 3) per-triangle corner values -> (n + 1, 3): corner 0, differences to corners 1 and 2, a zero row."""
    table = np.stack([values[:, 0], values[:, 1] - values[:, 0], values[:, 2] - values[:, 0]], axis=1)
    return np.vstack([table, np.zeros((1, 3))]).astype(np.float32)


def _triplanar(corners: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Texel coordinates (u, v) of each triangle's corners on the link frame's plane most facing its normal: the
    horizontal in-plane axis is u (a front's grain runs sideways, a top's along x)."""
    axis = np.argmax(np.abs(normals), axis=1)[:, None]
    u = np.where(axis == 0, corners[..., 1], corners[..., 0])
    v = np.where(axis == 2, corners[..., 1], corners[..., 2])
    return u * TEXELS_PER_M, v * TEXELS_PER_M


class Surfaces:
    """Base colour and gloss of the pixels a camera sees. `finishes` maps (body id, link index) to a `Finish`; it
    is read at every frame, so finishes set after the camera was made count."""

    def __init__(self, triangles: Triangles, finishes: Mapping[tuple[int, int], Finish]) -> None:
        self.triangles, self.finishes = triangles, finishes
        mats = triangles.materials
        rgb = np.array([m.rgb for m in mats], np.float64).reshape(-1, 3)
        self._material_rgb = srgb_to_linear(np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8))
        paths = sorted({m.texture for m in mats if m.texture is not None})
        self._textures = [texture_image(p) for p in paths]
        texture_of = {p: i for i, p in enumerate(paths)}
        material_texture = np.array([texture_of.get(m.texture, -1) for m in mats], np.int64)
        self._texture = material_texture.take(triangles.material) if len(mats) else np.zeros(0, np.int64)
        u, v = _triplanar(triangles.corners, triangles.normals)
        uvs = triangles.uvs
        for k, image in enumerate(self._textures):  # textured triangles: texel coordinates of their own image
            rows = self._texture == k
            h, w = image.shape[:2]
            u[rows], v[rows] = uvs[rows, :, 0] * w, (1.0 - uvs[rows, :, 1]) * h
        self._u, self._v = _corner_table(u), _corner_table(v)
        self._key: tuple | None = None

    def _tables(self) -> None:
        """Per-triangle colour, gloss and pattern tile of the current finishes (rebuilt when they change)."""
        tri = self.triangles
        finishes = [self.finishes.get(key) for key in tri.links]
        if self._key == tuple(finishes):
            return
        self._key = tuple(finishes)
        tiles = sorted({(f or UNFINISHED) for f in finishes}, key=repr)
        tile_of = {f: i + 1 for i, f in enumerate(tiles)}  # tile 0: flat, for textured triangles
        self._atlas = np.concatenate([np.ones(TILE_PX * TILE_PX, np.float32)]
                                     + [pattern(f.kind, f.seed).ravel() for f in tiles])
        link_tile = np.array([tile_of[f or UNFINISHED] for f in finishes], np.int64)
        link_rgb = np.array([(f or UNFINISHED).rgb for f in finishes], np.float32).reshape(-1, 3)
        link_gloss = np.array([(f or UNFINISHED).gloss for f in finishes], np.float32)
        finished = np.array([f is not None for f in finishes], bool).take(tri.link)
        rgb = np.where(finished[:, None], link_rgb.take(tri.link, axis=0),
                       self._material_rgb.take(tri.material, axis=0) if len(tri.link) else link_rgb[:0])
        self._rgb = [np.append(rgb[:, k], 0.0).astype(np.float32) for k in range(3)]
        self._gloss = np.append(link_gloss.take(tri.link), 0.0).astype(np.float32)
        tile = np.where((self._texture >= 0) & ~finished, 0, link_tile.take(tri.link))
        self._tile_offset = np.append(tile * TILE_PX * TILE_PX, 0)
        self._textured = np.append(np.where(finished, -1, self._texture), -1)

    def look(self, s: Surface) -> tuple[np.ndarray, np.ndarray]:
        """Base colour (3, n) linear and gloss (n,) of the hits of `s`."""
        self._tables()
        u, v = s.interpolate(self._u), s.interpolate(self._v)
        iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        shade = self._atlas.take(self._tile_offset.take(s.row) + (iv & (TILE_PX - 1)) * TILE_PX
                                 + (iu & (TILE_PX - 1)))
        rgb = np.stack([table.take(s.row) * shade for table in self._rgb])
        if self._textures:
            textured = self._textured.take(s.row)
            for k in np.flatnonzero(np.bincount(textured + 1, minlength=len(self._textures) + 1)[1:]):
                mask = textured == k
                image = self._textures[k]
                h, w = image.shape[:2]
                texel = image[np.mod(iv[mask], h), np.mod(iu[mask], w)]
                rgb[:, mask] *= texel.T
        return rgb, self._gloss.take(s.row)



def infrared_return(rgb: np.ndarray, gloss: np.ndarray) -> np.ndarray:
    """What a surface sends back of a projector's infrared: its base colour's luminance (a stand-in for its
    near-infrared albedo) times one minus gloss (a glossy surface sends the light on, not back)."""
    return (rgb[0] * _LUMA[0] + rgb[1] * _LUMA[1] + rgb[2] * _LUMA[2]) * (1.0 - gloss)
