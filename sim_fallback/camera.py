"""A simulated RealSense D415: PyBullet's TinyRenderer, metric depth with D415-like noise.

Its frames carry what a real camera's do: colour, depth, intrinsics and a timestamp. The simulator's answers
stay out of them unless asked for: `labels=True` adds the segmentation labels (the oracle ablation, scripted
data generation, tests) and `posed=True` the true camera pose (a real camera's pose comes from a calibration).

`read()` behaves like a camera streaming at `fps` on the simulated clock: it returns the frame of the
next frame slot, stepping the physics up to it when the slot has not come yet (the arm keeps its last
command meanwhile, as a real arm does while the program waits for a frame). When the caller is late,
the slots it missed are skipped and indices jump, like a real camera's latest frame.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb

from drivers.camera.base import Camera, Frame, Intrinsics, SegLabel
from drivers.camera.depth_noise import DepthNoise
from sim_fallback.world import SimWorld

D415_HFOV_DEG = 65.0  # depth field of view about 65 x 40 deg at 1280x720
NEAR_M, FAR_M = 0.1, 5.0  # clipping planes of the renderer; nothing beyond FAR_M reads valid depth
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera axes (y up, looking along -z) from OpenCV's


def d415_intrinsics(width: int = 640, height: int = 480) -> Intrinsics:
    """D415-like pinhole intrinsics: 65 deg horizontal field of view, centred principal point."""
    return Intrinsics.from_fov(width, height, D415_HFOV_DEG)


def projection_matrix(intrinsics: Intrinsics, near_m: float = NEAR_M, far_m: float = FAR_M) -> np.ndarray:
    """OpenGL projection (4x4) for TinyRenderer whose pixels follow the pinhole model u = fx X/Z + cx."""
    w, h = intrinsics.width, intrinsics.height
    P = np.zeros((4, 4))
    P[0, 0] = 2 * intrinsics.fx / w
    P[0, 2] = 1 - 2 * intrinsics.cx / w  # TinyRenderer's pixel centres, measured against plane geometry:
    P[1, 1] = 2 * intrinsics.fy / h  # column u at x_ndc = 2u/w - 1, row v at y_ndc = 1 - 2(v + 1)/h
    P[1, 2] = 2 * (intrinsics.cy + 1.0) / h - 1
    P[2, 2] = -(far_m + near_m) / (far_m - near_m)
    P[2, 3] = -2 * far_m * near_m / (far_m - near_m)
    P[3, 2] = -1.0
    return P


def depth_from_zbuffer(zbuffer: np.ndarray, near_m: float = NEAR_M, far_m: float = FAR_M) -> np.ndarray:
    """Metric depth (along the optical axis) from an OpenGL depth buffer; 0 where nothing was drawn
    (TinyRenderer clears to 1 - 6e-8 in float32, so the far plane itself counts as nothing)."""
    depth = np.multiply(np.asarray(zbuffer, np.float32), np.float32(near_m - far_m))  # float32: every frame
    depth += np.float32(far_m)
    np.divide(np.float32(far_m * near_m), depth, out=depth)
    depth[depth >= 0.999 * far_m] = 0.0
    return depth


def _gl_list(matrix: np.ndarray) -> list[float]:
    """PyBullet wants flat column-major lists: a 4x4 array silently renders wrong."""
    return [float(v) for v in np.asarray(matrix).T.ravel()]


class SimCamera(Camera):
    """A fixed third-person D415 in a `SimWorld` (default pose: the scenario's camera).

    intrinsics: default `d415_intrinsics()` (640x480; 1280x720 via `d415_intrinsics(1280, 720)`);
    noise: depth noise model (`DepthNoise.none()` gives exact depth); seed: noise and frame-drop stream;
    drop_rate: probability that a frame slot is dropped (its index is skipped); labels / posed: attach the
    segmentation labels / the true T_base_camera to each frame (ground truth: never for the controller).
    """

    def __init__(
        self,
        world: SimWorld,
        intrinsics: Intrinsics | None = None,
        noise: DepthNoise | None = None,
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
        self._clock = world.clock  # the camera keeps the clock and body ids, never the world's ground truth
        self._robot, self._cabinet, self._handle_link = world.robot_id, world.cabinet_id, world.handle_link
        self._intrinsics = intrinsics or d415_intrinsics()
        self.noise = DepthNoise.d415() if noise is None else noise
        self.fps = float(fps)
        self.drop_rate = float(drop_rate)
        self.T_base_camera = (world.scenario.T_base_camera if T_base_camera is None
                              else np.asarray(T_base_camera, float)).copy()
        self._view = _gl_list(np.linalg.inv(self.T_base_camera @ _GL_FROM_CV))
        self._proj = _gl_list(projection_matrix(self._intrinsics))
        self._seed = seed
        self.labels, self.posed = labels, posed
        self.connect()

    @property
    def intrinsics(self) -> Intrinsics:
        return self._intrinsics

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
        color, depth, segmentation = self.render()
        return Frame(index=slot, t=self._clock.time, color=color,
                     depth_m=self.noise.apply(depth, self._intrinsics.fx, self._rng),
                     intrinsics=self._intrinsics, T_base_camera=self.T_base_camera.copy() if self.posed else None,
                     segmentation=segmentation if self.labels else None)

    def render(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render now, without noise or stepping: colour (H,W,3) uint8, depth (H,W) float32 m, SegLabels."""
        w, h = self._intrinsics.width, self._intrinsics.height
        _, _, rgba, zbuffer, seg = pb.getCameraImage(
            w, h, self._view, self._proj, renderer=pb.ER_TINY_RENDERER, shadow=0,  # a shadow pass: +40%; sticky
            flags=pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX, physicsClientId=self._clock.client,
        )
        color = np.asarray(rgba, np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        depth = depth_from_zbuffer(np.asarray(zbuffer, np.float32).reshape(h, w))
        return color, depth, self._labels(np.asarray(seg, np.int32).reshape(h, w))

    def _labels(self, seg: np.ndarray) -> np.ndarray:
        """PyBullet's object/link buffer (object id = seg & 0xFFFFFF, link = (seg >> 24) - 1, -1 where
        nothing was drawn) as SegLabels."""
        body, link = seg & 0xFFFFFF, seg >> 24
        labels = np.zeros(seg.shape, np.uint8)  # SegLabel.BACKGROUND
        cabinet = body == self._cabinet
        labels[cabinet] = SegLabel.OBJECT
        labels[cabinet & (link == self._handle_link + 1)] = SegLabel.HANDLE
        labels[body == self._robot] = SegLabel.ROBOT
        return labels
