"""What one camera sees, frame after frame, lit by a few point lights (the room's lamp, the depth camera's
projector), with the part that only the static scene makes computed once.

While the camera and the static scene stay put, the static scene's hits, looks and light visibility are kept
(`_Layer`). A frame then casts only the pixels whose image rectangle holds a moving link at the dynamic scene,
tests the lights' visibility there, and, for the static pixels, only the rays toward a light that the moving links
may block (those inside the moving links' rectangle as the light sees them). Images derived from a frame
(`Seen.image`, e.g. shading) are recomputed only at the pixels that differ from the static layer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.camera.base import Intrinsics
from sim_fallback.render.rays import Surface, box_pixels, camera_rays, surface
from sim_fallback.render.scene import RayScene

SHADOW_OFFSET_M = 0.002  # rays toward a light start this far off the surface, along its normal
_AHEAD = 1e-3  # light-frame depth (m) below which a point counts as beside or behind a light


@dataclass(frozen=True)
class Light:
    """A point light at `position` (world, m) whose rays spread mostly along `axis` (unit): the axis only serves
    to find quickly which rays the moving links may block."""

    position: tuple[float, float, float]
    axis: tuple[float, float, float]

    def frame(self) -> np.ndarray:
        """(3, 3) rotation whose third row is the axis."""
        z = np.asarray(self.axis, float) / np.linalg.norm(self.axis)
        x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
        x /= np.linalg.norm(x)
        return np.stack([x, np.cross(z, x), z])


Look = Callable[[Surface], tuple[np.ndarray, np.ndarray]]  # surface -> (rgb (3, n) linear, gloss (n,))
Shader = Callable[[Surface, np.ndarray, np.ndarray, np.ndarray], np.ndarray]  # (s, rgb, gloss, lit) -> (k, n)


def lit_by(scene: RayScene, s: Surface, light: Light, static: bool = True, dynamic: bool = True) -> np.ndarray:
    """(n,) bool: whether `light` reaches each point of `s` (nothing of the chosen scenes in between)."""
    origin = s.point + SHADOW_OFFSET_M * s.normal
    to_light = np.asarray(light.position, np.float32)[:, None] - origin
    return ~scene.occluded(origin.T, to_light.T, 1.0, static, dynamic)


@dataclass
class _Layer:
    """The static scene as one camera pose sees it."""

    key: tuple
    directions: np.ndarray  # (H * W, 3) world rays
    surface: Surface  # every static hit, in pixel order
    rgb: np.ndarray
    gloss: np.ndarray
    lit: np.ndarray  # (lights, n) by the static scene
    position: np.ndarray  # (H * W,) each pixel's entry in `surface`, -1 where nothing
    depth: np.ndarray  # (H * W,) inf where nothing
    light_coords: list[np.ndarray]  # per light: (3, n) the points in its frame (x / z, y / z, z)
    images: dict


@dataclass
class Seen:
    """One frame: `depth` (H * W,) metres (0 where nothing); `row` (H * W,) the triangle (the triangle count where
    nothing); `rgb` (3, H * W) and `gloss` (H * W,) looks; `lit` (lights, H * W); `fresh` the hits that differ from
    the static layer (moving links, and static points whose light they block) with their looks and light."""

    depth: np.ndarray
    row: np.ndarray
    rgb: np.ndarray
    gloss: np.ndarray
    lit: np.ndarray
    fresh: Surface
    fresh_rgb: np.ndarray
    fresh_gloss: np.ndarray
    fresh_lit: np.ndarray
    _layer: _Layer

    def image(self, name: str, shader: Shader, background: tuple[float, ...] = (0.0,)) -> np.ndarray:
        """(k, H * W) image of `shader` (computed once per static layer for its pixels, then at the fresh ones);
        `background` (k,) where nothing is seen."""
        layer = self._layer
        if name not in layer.images:
            values = shader(layer.surface, layer.rgb, layer.gloss, layer.lit)
            image = np.empty((len(values), len(layer.depth)), np.float32)
            image[:] = np.asarray(background, np.float32)[:, None]
            image[:, layer.surface.index] = values
            layer.images[name] = image
        image = layer.images[name].copy()
        image[:, self.fresh.index] = shader(self.fresh, self.fresh_rgb, self.fresh_gloss, self.fresh_lit)
        return image


class CachedView:
    """A camera with `intrinsics` looking into `scene`, its lights' visibility, and the looks of what it sees."""

    def __init__(self, scene: RayScene, intrinsics: Intrinsics, look: Look) -> None:
        self.scene, self.intrinsics, self.look = scene, intrinsics, look
        self._rays = camera_rays(intrinsics)
        self._layer: _Layer | None = None

    def see(self, T_world_camera: np.ndarray, lights: tuple[Light, ...]) -> Seen:
        """The frame from `T_world_camera` (the scene updated for it)."""
        layer = self._static_layer(T_world_camera, lights)
        eye = T_world_camera[:3, 3].astype(np.float32)
        pixels = box_pixels(self.scene.dynamic_boxes(), T_world_camera, self.intrinsics)
        hits = self.scene.cast(eye, layer.directions[pixels], dynamic=True)
        nearer = hits.t < layer.depth[pixels]
        hits.t, hits.triangle, hits.uv = hits.t[nearer], hits.triangle[nearer], hits.uv[nearer]
        moving = surface(self.scene, eye, layer.directions[pixels][nearer], pixels[nearer], hits)
        covered = np.zeros(len(layer.surface.index), bool)
        covered[layer.position[moving.index][layer.position[moving.index] >= 0]] = True
        shadowed = np.zeros((len(lights), len(layer.surface.index)), bool)
        for k, light in enumerate(lights):
            maybe = np.flatnonzero(~covered & layer.lit[k] & self._maybe_blocked(layer, k, light))
            blocked = ~lit_by(self.scene, layer.surface.take(maybe), light, static=False)
            shadowed[k, maybe[blocked]] = True
        changed = np.flatnonzero(shadowed.any(axis=0))
        static_fresh = layer.surface.take(changed)
        moving_rgb, moving_gloss = self.look(moving)
        moving_lit = np.array([lit_by(self.scene, moving, light) for light in lights]).reshape(len(lights), -1)
        fresh = Surface.join(static_fresh, moving)
        fresh_rgb = np.concatenate([layer.rgb[:, changed], moving_rgb], axis=1)
        fresh_gloss = np.concatenate([layer.gloss[changed], moving_gloss])
        fresh_lit = np.concatenate([layer.lit[:, changed] & ~shadowed[:, changed], moving_lit], axis=1)

        n_pixels = len(layer.depth)
        depth = np.where(np.isfinite(layer.depth), layer.depth, 0.0).astype(np.float32)
        row = np.full(n_pixels, len(self.scene.triangles.link), np.int64)
        row[layer.surface.index] = layer.surface.row
        rgb = np.zeros((3, n_pixels), np.float32)
        rgb[:, layer.surface.index] = layer.rgb
        gloss = np.zeros(n_pixels, np.float32)
        gloss[layer.surface.index] = layer.gloss
        lit = np.zeros((len(lights), n_pixels), bool)
        lit[:, layer.surface.index] = layer.lit
        for image, values in ((depth, moving.depth), (row, moving.row), (gloss, moving_gloss)):
            image[moving.index] = values
        rgb[:, moving.index], lit[:, fresh.index] = moving_rgb, fresh_lit
        return Seen(depth, row, rgb, gloss, lit, fresh, fresh_rgb, fresh_gloss, fresh_lit, layer)

    def _static_layer(self, T_world_camera: np.ndarray, lights: tuple[Light, ...]) -> _Layer:
        key = (self.scene.version, T_world_camera.tobytes(), lights)
        if self._layer is not None and self._layer.key == key:
            return self._layer
        R, eye = T_world_camera[:3, :3].astype(np.float32), T_world_camera[:3, 3].astype(np.float32)
        directions = self._rays @ R.T
        pixels = np.arange(len(directions))
        s = surface(self.scene, eye, directions, pixels, self.scene.cast(eye, directions, dynamic=False))
        rgb, gloss = self.look(s)
        lit = np.array([lit_by(self.scene, s, light, dynamic=False) for light in lights]).reshape(len(lights), -1)
        position = np.full(len(pixels), -1, np.int64)
        position[s.index] = np.arange(len(s.index))
        depth = np.full(len(pixels), np.inf, np.float32)
        depth[s.index] = s.depth
        coords = []
        for light in lights:
            q = light.frame().astype(np.float32) @ (s.point - np.asarray(light.position, np.float32)[:, None])
            z = q[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                coords.append(np.stack([q[0] / z, q[1] / z, z]))
        self._layer = _Layer(key, directions, s, rgb, gloss, lit, position, depth, coords, {})
        return self._layer

    def _maybe_blocked(self, layer: _Layer, k: int, light: Light) -> np.ndarray:
        """(n,) bool over the static hits: the moving links may lie between the point and light `k`."""
        boxes = self.scene.dynamic_boxes()
        coords = layer.light_coords[k]
        if not boxes:
            return np.zeros(coords.shape[1], bool)
        corners = np.concatenate([[[(lo, hi)[i >> 2 & 1][0], (lo, hi)[i >> 1 & 1][1], (lo, hi)[i & 1][2]]
                                   for i in range(8)] for lo, hi in boxes])
        q = light.frame() @ (corners - np.asarray(light.position)).T
        behind = ~(coords[2] > _AHEAD)  # beside or behind the light: always tested
        if q[2].min() <= _AHEAD:
            return np.ones(coords.shape[1], bool)
        a, b = q[0] / q[2], q[1] / q[2]
        inside = (coords[0] >= a.min()) & (coords[0] <= a.max()) & (coords[1] >= b.min()) & (coords[1] <= b.max())
        return behind | (inside & (coords[2] > q[2].min()))
