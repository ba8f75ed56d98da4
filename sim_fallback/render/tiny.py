"""PyBullet's TinyRenderer as a renderer of the simulated camera: flat colours, no shadows, textures as PyBullet
holds them. The calibration scenes use it, since their board is a mesh given to PyBullet as arrays with a texture
only PyBullet knows (the ray-casting renderer draws what files describe)."""

from __future__ import annotations

import numpy as np
import pybullet as pb

from drivers.camera.base import Intrinsics
from sim_fallback.render.renderer import Render

NEAR_M, FAR_M = 0.1, 5.0  # clipping planes; nothing beyond FAR_M reads valid depth
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera axes (y up, looking along -z) from OpenCV's
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


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
    depth = np.multiply(np.asarray(zbuffer, np.float32), np.float32(near_m - far_m))  # float32: 4x faster
    depth += np.float32(far_m)
    np.divide(np.float32(far_m * near_m), depth, out=depth)
    depth[depth >= 0.999 * far_m] = 0.0
    return depth


def _gl_list(matrix: np.ndarray) -> list[float]:
    """PyBullet wants flat column-major lists: a 4x4 array silently renders wrong."""
    return [float(v) for v in np.asarray(matrix).T.ravel()]


class TinyRenderer:
    """Renders a PyBullet client through a pinhole camera of `intrinsics` with TinyRenderer."""

    def __init__(self, client: int, intrinsics: Intrinsics) -> None:
        self.client, self.intrinsics = client, intrinsics
        self._proj = _gl_list(projection_matrix(intrinsics))

    def render(self, T_base_camera: np.ndarray, _rng: np.random.Generator, _extra_lights: tuple = ()) -> Render:
        """Colour, depth, links and (the colour's luminance as) infrared return of the view now (extra lights, such
        as a projector, are not drawn)."""
        w, h = self.intrinsics.width, self.intrinsics.height
        view = _gl_list(np.linalg.inv(T_base_camera @ _GL_FROM_CV))
        _, _, rgba, zbuffer, seg = pb.getCameraImage(
            w, h, view, self._proj, renderer=pb.ER_TINY_RENDERER, shadow=0,
            flags=pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX, physicsClientId=self.client,
        )
        color = np.asarray(rgba, np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        depth = depth_from_zbuffer(np.asarray(zbuffer, np.float32).reshape(h, w))
        seg = np.asarray(seg, np.int32).reshape(h, w)
        links = np.stack([np.where(seg < 0, -1, seg & 0xFFFFFF), np.where(seg < 0, -1, (seg >> 24) - 1)], axis=-1)
        reflectance = np.where(depth > 0, (color.astype(np.float32) / 255.0) @ _LUMA, 0.0).astype(np.float32)
        return Render(color, depth, links.astype(np.int32), reflectance, None)
