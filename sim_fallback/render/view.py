"""What one camera sees, frame after frame, lit by a few point lights (the room's lamp, the depth camera's
projector), with the part that only the static scene makes computed once.

While the camera and the static scene stay put, the static scene's hits, looks and light visibility are kept
(`_Layer`). A frame then casts only the pixels whose image rectangle holds a moving link at the dynamic scene,
tests the lights' visibility there, and, for the static pixels, only the rays toward a light that the moving links
may block (those inside the moving links' rectangle as the light sees them), one per 2 x 2 block of pixels (the
moving links' shadows on static surfaces have 2-pixel steps). Images derived from a frame (`Seen.image`, e.g.
shading) are recomputed only at the pixels that differ from the static layer.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.camera.base import Intrinsics
from sim_fallback.render.rays import Surface, box_pixels, camera_rays, surface
from sim_fallback.render.scene import RayScene
from sim_fallback.render.surfaces import infrared_return

SHADOW_OFFSET_M = 0.002  # rays toward a light start this far off the surface, along its normal
_AHEAD = 1e-3  # light-frame depth (m) below which a point counts as beside or behind a light


class _Stopwatch:
    """Milliseconds spent per named step."""

    def __init__(self) -> None:
        self.laps: dict[str, float] = {}
        self._last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = self.laps.get(name, 0.0) + 1e3 * (now - self._last)
        self._last = now


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
    """The static scene as one camera pose sees it: its hits (`surface`, in pixel order) with their looks and
    light, the same as whole images (`depth` 0 and `row` the triangle count where nothing), and the hits that
    stand for their 2 x 2 block of pixels when testing what the moving links shadow."""

    key: tuple
    directions: np.ndarray  # (H * W, 3) world rays
    surface: Surface
    rgb: np.ndarray
    gloss: np.ndarray
    lit: np.ndarray  # (lights, n) by the static scene
    position: np.ndarray  # (H * W,) each pixel's entry in `surface`, -1 where nothing
    depth: np.ndarray
    row: np.ndarray
    reflectance: np.ndarray
    lit_image: np.ndarray
    anchors: np.ndarray  # entries at the top-left of their 2 x 2 block (or alone in it)
    members: np.ndarray  # (anchors, 4) the entries of each anchor's block, -1 padded
    anchor_coords: list[np.ndarray]  # per light: (3, anchors) the anchors in its frame (x / z, y / z, z)
    images: dict


@dataclass
class Seen:
    """One frame: `depth` (H * W,) metres (0 where nothing); `row` (H * W,) the triangle (the triangle count where
    nothing); `reflectance` (H * W,) the infrared return (`infrared_return`); `lit` (lights, H * W); `fresh` the
    hits that differ from
    the static layer (moving links, and static points whose light they block) with their looks and light;
    `timings_ms`: cast (rays, hits), surfaces (looks), shadows (light visibility)."""

    depth: np.ndarray
    row: np.ndarray
    reflectance: np.ndarray
    lit: np.ndarray
    fresh: Surface
    fresh_rgb: np.ndarray
    fresh_gloss: np.ndarray
    fresh_lit: np.ndarray
    _layer: _Layer
    timings_ms: dict[str, float]

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
        self._position = np.full(intrinsics.width * intrinsics.height, -1, np.int32)

    def see(self, T_world_camera: np.ndarray, lights: tuple[Light, ...]) -> Seen:
        """The frame from `T_world_camera` (the scene updated for it)."""
        clock = _Stopwatch()
        layer = self._static_layer(T_world_camera, lights, clock)
        eye = T_world_camera[:3, 3].astype(np.float32)
        pixels = box_pixels(self.scene.dynamic_boxes(), T_world_camera, self.intrinsics)
        hits = self.scene.cast(eye, layer.directions[pixels], dynamic=True)
        behind = layer.depth[pixels]
        nearer = np.flatnonzero((hits.t < behind) | ((behind == 0) & np.isfinite(hits.t)))
        hits.t, hits.triangle, hits.uv = hits.t[nearer], hits.triangle[nearer], hits.uv[nearer]
        moving = surface(self.scene, eye, layer.directions[pixels[nearer]], pixels[nearer], hits)
        clock.lap("cast")
        shadowed = np.zeros((len(lights), len(layer.surface.index)), bool)
        for k, light in enumerate(lights):
            tested = np.flatnonzero(self._maybe_blocked(layer, k, light))
            blocked = ~lit_by(self.scene, layer.surface.take(layer.anchors[tested]), light, static=False)
            members = layer.members[tested[blocked]].ravel()
            shadowed[k, members[members >= 0]] = True
        changed = np.flatnonzero(shadowed.any(axis=0))
        moving_lit = self._moving_lit(moving, lights)
        clock.lap("shadows")
        moving_rgb, moving_gloss = self.look(moving)
        fresh = Surface.join(layer.surface.take(changed), moving)
        fresh_rgb = np.concatenate([layer.rgb[:, changed], moving_rgb], axis=1)
        fresh_gloss = np.concatenate([layer.gloss[changed], moving_gloss])
        fresh_lit = np.concatenate([layer.lit[:, changed] & ~shadowed[:, changed], moving_lit], axis=1)
        depth, row = layer.depth.copy(), layer.row.copy()
        reflectance, lit = layer.reflectance.copy(), layer.lit_image.copy()
        depth[moving.index], row[moving.index] = moving.depth, moving.row
        reflectance[moving.index] = infrared_return(moving_rgb, moving_gloss)
        lit[:, fresh.index] = fresh_lit
        clock.lap("surfaces")
        return Seen(depth, row, reflectance, lit, fresh, fresh_rgb, fresh_gloss, fresh_lit, layer, clock.laps)

    def _moving_lit(self, moving: Surface, lights: tuple[Light, ...]) -> np.ndarray:
        """(lights, n) visibility of the lights at the moving links' hits, tested at one hit per 2 x 2 block of
        pixels on the same triangle (the block's top-left one where it is such a hit)."""
        w = self.intrinsics.width
        position = self._position  # -1 everywhere between calls
        position[moving.index] = np.arange(len(moving.index), dtype=np.int32)
        rows, cols = np.divmod(moving.index, w)
        anchor = position[(rows - rows % 2) * w + cols - cols % 2]
        position[moving.index] = -1
        own = np.arange(len(anchor), dtype=np.int32)
        anchor = np.where((anchor >= 0) & (moving.row[np.maximum(anchor, 0)] == moving.row), anchor, own)
        tested = np.flatnonzero(anchor == own)
        lit = np.zeros((len(lights), len(anchor)), bool)
        for k, light in enumerate(lights):
            lit[k, tested] = lit_by(self.scene, moving.take(tested), light)
        return lit[:, anchor]

    def _static_layer(self, T_world_camera: np.ndarray, lights: tuple[Light, ...], clock: _Stopwatch) -> _Layer:
        key = (self.scene.version, T_world_camera.tobytes(), lights)
        if self._layer is not None and self._layer.key == key:
            return self._layer
        self._layer = self._build_layer(key, T_world_camera, lights)
        clock.lap("static layer")
        return self._layer

    def _build_layer(self, key: tuple, T_world_camera: np.ndarray, lights: tuple[Light, ...]) -> _Layer:
        R, eye = T_world_camera[:3, :3].astype(np.float32), T_world_camera[:3, 3].astype(np.float32)
        directions = self._rays @ R.T
        n_pixels = len(directions)
        s = surface(self.scene, eye, directions, np.arange(n_pixels), self.scene.cast(eye, directions, dynamic=False))
        rgb, gloss = self.look(s)
        lit = np.array([lit_by(self.scene, s, light, dynamic=False) for light in lights]).reshape(len(lights), -1)
        position = np.full(n_pixels, -1, np.int64)
        position[s.index] = np.arange(len(s.index))
        depth = np.zeros(n_pixels, np.float32)
        row = np.full(n_pixels, len(self.scene.triangles.link), np.int32)
        reflectance, lit_image = np.zeros(n_pixels, np.float32), np.zeros((len(lights), n_pixels), bool)
        depth[s.index], row[s.index], reflectance[s.index] = s.depth, s.row, infrared_return(rgb, gloss)
        lit_image[:, s.index] = lit
        w = self.intrinsics.width
        rows, cols = np.divmod(s.index, w)
        anchor = position[(rows - rows % 2) * w + cols - cols % 2]
        anchor = np.where(anchor >= 0, anchor, np.arange(len(anchor)))
        anchors = np.flatnonzero(anchor == np.arange(len(anchor)))
        slot = np.full(len(anchor), -1, np.int64)
        slot[anchors] = np.arange(len(anchors))
        slot = slot[anchor]  # each entry's anchor, as a row of `members`
        order = np.argsort(slot, kind="stable")
        starts = np.searchsorted(slot[order], np.arange(len(anchors)))
        members = np.full((len(anchors), 4), -1, np.int64)
        members[slot[order], np.arange(len(order)) - starts[slot[order]]] = order
        coords = []
        for light in lights:
            p = s.point[:, anchors] - np.asarray(light.position, np.float32)[:, None]
            q = light.frame().astype(np.float32) @ p
            with np.errstate(divide="ignore", invalid="ignore"):
                coords.append(np.stack([q[0] / q[2], q[1] / q[2], q[2]]))
        return _Layer(key, directions, s, rgb, gloss, lit, position, depth, row, reflectance, lit_image, anchors,
                      members, coords, {})

    def _maybe_blocked(self, layer: _Layer, k: int, light: Light) -> np.ndarray:
        """(anchors,) bool: lit by light `k` in the static scene, and the moving links may lie between the anchor
        and the light (inside their rectangle as the light sees them, and farther)."""
        boxes = self.scene.dynamic_boxes()
        coords = layer.anchor_coords[k]
        lit = layer.lit[k, layer.anchors]
        if not len(boxes):
            return np.zeros(coords.shape[1], bool)
        q = light.frame() @ (boxes.reshape(-1, 3) - np.asarray(light.position)).T
        if q[2].min() <= _AHEAD:
            return lit
        a, b = q[0] / q[2], q[1] / q[2]
        inside = (coords[0] >= a.min()) & (coords[0] <= a.max()) & (coords[1] >= b.min()) & (coords[1] <= b.max())
        behind = ~(coords[2] > _AHEAD)  # beside or behind the light: always tested
        return lit & (behind | (inside & (coords[2] > q[2].min())))
