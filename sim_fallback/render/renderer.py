"""The simulated colour-and-depth camera's renderer: ray casting into a PyBullet client's visual shapes
(sim_fallback.render.scene, view), surface looks (surfaces), a room's light with the lamp's shadows and the colour
camera's exposure and noise (lighting).

`render` gives what the camera's sensors see before the depth model: the colour image, exact depth, the (body id,
link index) seen at each pixel (truth), and each pixel's infrared return (what the D415's projector gets back
from the surface: diffuse albedo times one minus gloss), which the depth models use.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from functools import cached_property

import numpy as np

from drivers.camera.base import Intrinsics
from sim_fallback.furniture import Finish
from sim_fallback.render.lighting import BACKGROUND_RGB, Exposure, Lighting
from sim_fallback.render.scene import RayScene
from sim_fallback.render.surfaces import Surfaces
from sim_fallback.render.view import CachedView, Light, Seen


class Render:
    """One rendered view: `color` (H, W, 3) uint8; `depth_m` (H, W) float32 exact, 0 where nothing; `links`
    (H, W, 2) int32 (body id, link index; -1 for a base; (-1, -1) where nothing; made when first asked for);
    `reflectance` (H, W) float32 infrared return in 0-1 (0 where nothing); `seen` the frame's geometry and lights
    (for depth models that render more); `timings_ms` of the steps (scene: poses and rebuilds; static layer: what a
    new camera pose or static scene costs once; cast; shadows; surfaces; shading; exposure: colour noise and
    encoding)."""

    def __init__(self, color: np.ndarray, depth_m: np.ndarray, links: Callable[[], np.ndarray] | np.ndarray,
                 reflectance: np.ndarray, seen: Seen | None, timings_ms: dict[str, float] | None = None) -> None:
        self.color, self.depth_m, self.reflectance, self.seen = color, depth_m, reflectance, seen
        self.timings_ms = timings_ms or {}
        self._links = links

    @cached_property
    def links(self) -> np.ndarray:
        return self._links() if callable(self._links) else self._links


class RayRenderer:
    """Renders a PyBullet client through a pinhole camera of `intrinsics`.

    finishes: (body id, link index) -> `Finish`, read at every frame; seed: the room's light, the exposure bias
    and the colour noise.
    """

    def __init__(self, client: int, intrinsics: Intrinsics, finishes: Mapping[tuple[int, int], Finish] | None = None,
                 seed: int = 0, threads: int = 1) -> None:
        self.intrinsics, self.seed = intrinsics, seed
        self.scene = RayScene(client, threads)
        self._finishes = {} if finishes is None else finishes
        self._surfaces = Surfaces(self.scene.triangles, self._finishes)
        self._lighting: Lighting | None = None
        self._exposure = Exposure((intrinsics.height, intrinsics.width), seed)
        self._views: dict[str, CachedView] = {}

    def update(self) -> None:
        """Read the world's poses for a new frame (`render` does it)."""
        triangles = self.scene.triangles
        self.scene.update()
        if self.scene.triangles is not triangles:
            self._surfaces = Surfaces(self.scene.triangles, self._finishes)
            self._views.clear()

    def view(self, name: str = "colour") -> CachedView:
        """The cached view called `name` (one per camera pose that is rendered every frame), at the renderer's
        intrinsics."""
        if name not in self._views:
            self._views[name] = CachedView(self.scene, self.intrinsics, lambda s: self._surfaces.look(s))
        return self._views[name]

    def see(self, name: str, T_base_camera: np.ndarray, extra_lights: tuple[Light, ...] = ()) -> Seen:
        """The frame of the view `name` from `T_base_camera` with the room's lamp and `extra_lights` (after
        `render` updated the scene for this frame): another camera of a rig, e.g. a stereo pair's right one."""
        lamp = self.lighting(T_base_camera).lamp
        return self.view(name).see(T_base_camera, (lamp, *extra_lights))

    def lighting(self, T_base_camera: np.ndarray) -> Lighting:
        """The room's light, placed from the first view rendered."""
        if self._lighting is None:
            self._lighting = Lighting.room(T_base_camera, self.seed)
        return self._lighting

    def link_image(self, row: np.ndarray) -> np.ndarray:
        """(H, W, 2) int32 (body id, link index) of the triangles `row` (H * W,), (-1, -1) where nothing."""
        tri = self.scene.triangles
        table = np.vstack([np.asarray(tri.links, np.int32).reshape(-1, 2), [[-1, -1]]])
        links = np.append(tri.link, len(table) - 1)
        K = self.intrinsics
        return table.take(links.take(row), axis=0).reshape(K.height, K.width, 2)

    def links(self, T_base_camera: np.ndarray) -> np.ndarray:
        """(H, W, 2) int32 (body id, link index) seen at each pixel now, (-1, -1) where nothing (truth)."""
        self.update()
        return self.link_image(self.see("colour", T_base_camera).row)

    def render(self, T_base_camera: np.ndarray, rng: np.random.Generator, extra_lights: tuple[Light, ...] = ()
               ) -> Render:
        """Colour, exact depth, links and infrared return of the view from `T_base_camera` now; `extra_lights`
        (e.g. a projector) are seen too (lights 1... of `Render.seen`) but do not light the colour image."""
        start = time.perf_counter()
        self.update()
        lighting = self.lighting(T_base_camera)
        seen = self.view().see(T_base_camera, (lighting.lamp, *extra_lights))
        timings = {"scene": 1e3 * (time.perf_counter() - start), **seen.timings_ms}
        start = time.perf_counter()
        radiance = seen.image("colour", lighting.shade, BACKGROUND_RGB)
        timings["shading"] = 1e3 * (time.perf_counter() - start)
        start = time.perf_counter()
        color = self._exposure.image(radiance, rng)
        K = self.intrinsics
        shape = (K.height, K.width)
        out = Render(color, seen.depth.reshape(shape), lambda: self.link_image(seen.row),
                     seen.reflectance.reshape(shape), seen, timings)
        timings["exposure"] = 1e3 * (time.perf_counter() - start)
        timings["scene"] -= sum(seen.timings_ms.values())  # reading the poses, rebuilding the scenes
        return out
