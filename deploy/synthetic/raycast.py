"""A small ray caster for scenes of oriented boxes (slab method, vectorised numpy).

Camera convention: OpenCV (x right, y down, z forward); `T_base_camera` is the camera pose in the
base frame. Pixels that hit nothing get depth 0 and label 0 (`SegLabel.BACKGROUND`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from deploy.geometry.types import Box
from drivers.camera.base import Intrinsics, SegLabel

LABEL_RGB = {
    SegLabel.BACKGROUND: (150, 146, 140),
    SegLabel.OBJECT: (181, 136, 92),
    SegLabel.HANDLE: (200, 200, 210),
    SegLabel.ROBOT: (230, 230, 230),
}
_SKY_RGB = (60, 60, 64)
_AMBIENT = 0.3


def _cast(
    boxes: Sequence[tuple[Box, SegLabel]], intrinsics: Intrinsics, T_base_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depth (m, 0 = miss), label and |cos| between view ray and surface normal, per pixel.

    Pixel rays are (x, y, 1) in the camera frame, so the ray parameter at a hit is the depth. Each
    box is tested only on the pixels of its projected bounding rectangle.
    """
    h, w = intrinsics.height, intrinsics.width
    xs = (np.arange(w) - intrinsics.cx) / intrinsics.fx
    ys = (np.arange(h) - intrinsics.cy) / intrinsics.fy
    T = np.asarray(T_base_camera, float)
    R, p = T[:3, :3], T[:3, 3]
    depth = np.full((h, w), np.inf)
    labels = np.zeros((h, w), np.uint8)
    cos = np.zeros((h, w))
    for box, label in boxes:
        rows, cols = _covering_rect(box, intrinsics, R, p)
        if rows.start >= rows.stop or cols.start >= cols.stop:
            continue
        x, y = xs[cols][None, :], ys[rows][:, None]
        M = R.T @ box.rotation  # camera-frame ray (x, y, 1) -> box frame: (x, y, 1) @ M
        origin = (p - box.center) @ box.rotation  # the camera centre in the box frame
        t_in = np.full((rows.stop - rows.start, cols.stop - cols.start), -np.inf)
        t_out = np.full_like(t_in, np.inf)
        d_face = np.zeros_like(t_in)
        with np.errstate(divide="ignore", invalid="ignore"):
            for k in range(3):
                d = x * M[0, k] + y * M[1, k] + M[2, k]
                t_a = (-box.extent[k] / 2 - origin[k]) / d
                t_b = (box.extent[k] / 2 - origin[k]) / d
                near = np.minimum(t_a, t_b)
                entering = near > t_in
                t_in = np.where(entering, near, t_in)
                d_face = np.where(entering, np.abs(d), d_face)
                t_out = np.minimum(t_out, np.maximum(t_a, t_b))
        view = depth[rows, cols]
        hit = (t_in > 0) & (t_in <= t_out) & (t_in < view)
        view[hit] = t_in[hit]
        labels[rows, cols][hit] = label
        cos[rows, cols][hit] = (d_face / np.sqrt(x * x + y * y + 1.0))[hit]
    depth[~np.isfinite(depth)] = 0.0
    return depth.astype(np.float32), labels, cos


def _covering_rect(box: Box, intrinsics: Intrinsics, R: np.ndarray, p: np.ndarray) -> tuple[slice, slice]:
    """Row and column slices of the box's projected bounding rectangle (the whole image if it crosses
    the camera plane; empty if off-screen)."""
    h, w = intrinsics.height, intrinsics.width
    corners = (box.corners() - p) @ R
    if np.any(corners[:, 2] <= 1e-6):
        return slice(0, h), slice(0, w)
    u = intrinsics.fx * corners[:, 0] / corners[:, 2] + intrinsics.cx
    v = intrinsics.fy * corners[:, 1] / corners[:, 2] + intrinsics.cy
    cols = slice(max(int(np.floor(u.min())), 0), min(int(np.ceil(u.max())) + 1, w))
    rows = slice(max(int(np.floor(v.min())), 0), min(int(np.ceil(v.max())) + 1, h))
    return rows, cols


def render(
    boxes: Sequence[tuple[Box, SegLabel]], intrinsics: Intrinsics, T_base_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Depth (H, W) float32 metres (0 = nothing hit) and labels (H, W) uint8 of the nearest box per pixel."""
    depth, labels, _ = _cast(boxes, intrinsics, T_base_camera)
    return depth, labels


def render_rgbd(
    boxes: Sequence[tuple[Box, SegLabel]], intrinsics: Intrinsics, T_base_camera: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Colour (H, W, 3) uint8 RGB (label colour times a head-light Lambert term), depth and labels."""
    depth, labels, cos = _cast(boxes, intrinsics, T_base_camera)
    palette = np.array([LABEL_RGB.get(SegLabel(i), _SKY_RGB) for i in range(len(SegLabel))], np.float32)
    shade = (_AMBIENT + (1 - _AMBIENT) * cos).astype(np.float32)
    color = (palette[labels] * shade[..., None] + 0.5).astype(np.uint8)
    color[depth == 0] = _SKY_RGB
    return color, depth, labels
