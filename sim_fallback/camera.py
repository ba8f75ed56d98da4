"""A simulated RealSense D415: colour with light, shadows, textures, exposure and noise, and depth as a D415
measures it (sim_fallback.render: ray casting into the PyBullet world).

Its frames carry what a real camera's do: colour, depth, intrinsics and a timestamp. The simulator's answers
stay out of them unless asked for: `labels=True` adds the segmentation labels (the oracle ablation, scripted
data generation, tests) and `posed=True` the true camera pose (a real camera's pose comes from a calibration).
`link_image()` gives the (body id, link index) seen at each pixel, for evaluation only.

Depth comes from one of two models: `DepthNoise` (drivers.camera.depth_noise: D415 artefacts computed from the
exact depth and each pixel's infrared return; the default, `DepthNoise.d415()`) or `ActiveStereo` (the two
infrared views with the projector's dots, matched by OpenCV's SGBM). docs/simulation.md compares them.

`read()` behaves like a camera streaming at `fps` on the simulated clock: it returns the frame of the
next frame slot, stepping the physics up to it when the slot has not come yet (the arm keeps its last
command meanwhile, as a real arm does while the program waits for a frame). When the caller is late,
the slots it missed are skipped and indices jump, like a real camera's latest frame.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drivers.camera.base import Camera, Frame, Intrinsics, SegLabel
from drivers.camera.depth_noise import DepthNoise
from sim_fallback.render.renderer import RayRenderer, Render
from sim_fallback.render.stereo import ActiveStereo
from sim_fallback.world import SimWorld

D415_HFOV_DEG = 65.0  # depth field of view about 65 x 40 deg at 1280x720


def d415_intrinsics(width: int = 640, height: int = 480) -> Intrinsics:
    """D415-like pinhole intrinsics: 65 deg horizontal field of view, centred principal point."""
    return Intrinsics.from_fov(width, height, D415_HFOV_DEG)


class SimCamera(Camera):
    """A fixed third-person D415 in a `SimWorld` (default pose: the scenario's camera).

    intrinsics: default `d415_intrinsics()` (640x480; 1280x720 via `d415_intrinsics(1280, 720)`);
    noise: the depth model: a `DepthNoise` (`DepthNoise.none()` gives exact depth) or an `ActiveStereo`
    (default `DepthNoise.d415()`); seed: light, exposure, noise and frame-drop stream; drop_rate: probability that a
    frame slot is dropped (its index is skipped); labels / posed: attach the segmentation labels / the true
    T_base_camera to each frame (ground truth: never for the controller).
    """

    def __init__(
        self,
        world: SimWorld,
        intrinsics: Intrinsics | None = None,
        noise: DepthNoise | ActiveStereo | None = None,
        seed: int = 0,
        drop_rate: float = 0.0,
        fps: float = 10.0,
        T_base_camera: np.ndarray | None = None,
        labels: bool = False,
        posed: bool = False,
    ) -> None:
        rate = 1.0 / world.clock.dt  # one frame per physics step at most
        if not 0 < fps <= rate + 1e-9 or not 0.0 <= drop_rate < 1.0:
            raise ValueError(f"SimCamera: fps must be in (0, {rate:g}], the physics rate (got {fps}), drop_rate in "
                             f"[0, 1) (got {drop_rate})")
        self._clock = world.clock  # the camera keeps the clock, body ids and looks, never the world's ground truth
        self._robot, self._cabinet, self._handle_link = world.robot_id, world.cabinet_id, world.handle_link
        self._intrinsics = intrinsics or d415_intrinsics()
        self.noise = DepthNoise.d415() if noise is None else noise
        self._stereo = self.noise if isinstance(self.noise, ActiveStereo) else None  # the one model that renders
        self.fps = float(fps)
        self.drop_rate = float(drop_rate)
        self.T_base_camera = (world.scenario.T_base_camera if T_base_camera is None
                              else np.asarray(T_base_camera, float)).copy()
        self._seed = seed
        self.labels, self.posed = labels, posed
        self.timings_ms: dict[str, float] = {}  # what the last frame read cost, by step
        self._renderer = self._make_renderer(world)
        self.connect()

    def _make_renderer(self, world: SimWorld):
        """The renderer (a `RayRenderer`; calibration scenes draw with PyBullet's TinyRenderer)."""
        return RayRenderer(world.client, self._intrinsics, world.finishes, self._seed)

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

    @property
    def depth_model(self) -> str:
        """Which depth model the camera measures with, as reports name it."""
        if self._stereo is not None:
            return "active stereo (SGBM on the projector's dots)"
        known = {DepthNoise.d415(): "D415 artefact model", DepthNoise.none(): "exact"}
        return known.get(self.noise, "artefact model (custom)")

    def connect(self) -> None:
        """(Re)start the stream: the next frame is the next slot; the noise stream restarts from the seed."""
        self._rng = np.random.default_rng(self._seed)
        self._last_slot = math.floor(self._clock.time * self.fps - 1e-9) - 1

    def read(self, timeout_s: float = 2.0) -> Frame:
        slot = max(self._last_slot + 1, math.floor(self._clock.time * self.fps + 1e-9))
        if self.drop_rate > 0:
            while self._rng.random() < self.drop_rate:
                slot += 1
        steps_needed = math.ceil(slot / self.fps / self._clock.dt - 1e-6) - self._clock.steps
        if steps_needed > 0:
            self._clock.step(steps_needed)
        self._last_slot = slot
        view = self._capture()
        start = time.perf_counter()
        depth = self._depth(view)
        self.timings_ms = {**view.timings_ms, "depth model": 1e3 * (time.perf_counter() - start)}
        return Frame(index=slot, t=self._clock.time, color=view.color, depth_m=depth,
                     intrinsics=self._intrinsics, T_base_camera=self.T_base_camera.copy() if self.posed else None,
                     segmentation=self._labels(_pybullet_ids(view.links)) if self.labels else None)

    def _capture(self) -> Render:
        """Render now (with the projector seen when the depth model is stereo)."""
        extra = () if self._stereo is None else (self._stereo.projector(self.T_base_camera),)
        return self._renderer.render(self.T_base_camera, self._rng, extra)

    def _depth(self, view: Render) -> np.ndarray:
        if self._stereo is None:
            return self.noise.apply(view.depth_m, self._intrinsics.fx, self._rng, reflectance=view.reflectance)
        T, projector = self.T_base_camera, self._stereo.projector(self.T_base_camera)
        right = self._renderer.see("right", self._stereo.right(T), (projector,))
        return self._stereo.measure(view.seen, right, T, self._intrinsics, self._rng)

    def render(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render now, without stepping: colour (H,W,3) uint8, exact depth (H,W) float32 m, SegLabels."""
        view = self._capture()
        return view.color, view.depth_m, self._labels(_pybullet_ids(view.links))

    def link_image(self) -> np.ndarray:
        """(H, W, 2) int32 (body id, link index; -1 for a base) seen at each pixel now, (-1, -1) where nothing:
        ground truth for evaluation (e.g. a simulated user's pixel on a part), never for the controller. It draws
        nothing from the camera's noise stream: its frames are the same whether it is called or not."""
        return self._renderer.links(self.T_base_camera)

    def _labels(self, seg: np.ndarray) -> np.ndarray:
        """SegLabels from PyBullet-style object/link ids (object id = seg & 0xFFFFFF, link = (seg >> 24) - 1, -1
        where nothing)."""
        body, link = seg & 0xFFFFFF, seg >> 24
        labels = np.zeros(seg.shape, np.uint8)  # SegLabel.BACKGROUND
        cabinet = body == self._cabinet
        labels[cabinet] = SegLabel.OBJECT
        labels[cabinet & (link == self._handle_link + 1)] = SegLabel.HANDLE
        labels[body == self._robot] = SegLabel.ROBOT
        return labels


def _pybullet_ids(links: np.ndarray) -> np.ndarray:
    """(H, W) PyBullet segmentation ids (body | (link + 1) << 24, -1 where nothing) of a (body, link) image."""
    body, link = links[..., 0], links[..., 1]
    return np.where(body < 0, -1, body | ((link + 1) << 24)).astype(np.int32)
