"""A front's plane seen face-on: the camera image resampled onto a grid in the plane (a rectified view).

Plane frame (base frame, metres): `origin` on the plane, `normal` out of it toward the camera, `right` horizontal
in the plane (to the right of someone facing it), `up` in the plane (the base frame's up made perpendicular to the
normal). Grid: column c at s = s_min + c * res_m along `right`, row r at z = z_max - r * res_m along `up` (the
rectified image is upright, as someone facing the plane sees it).

Each grid cell carries what the camera saw there: the grey level, the colour (Lab), whether it is seen at all
(inside the image, not the arm), the measured depth's offset from the plane along its normal (positive: nearer the
camera than the plane) and the D415's depth noise there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from drivers.camera.base import Frame
from drivers.camera.depth_noise import DepthNoise

UP = np.array([0.0, 0.0, 1.0])
D415 = DepthNoise.d415()  # the sensor's axial noise model: sigma_z = z^2 * subpixel / (fx * baseline)
NOISE_SIGMAS = 3.0  # a surface point lies within this many sigmas of its plane (99.7 %)
QUANTUM_M = 0.002  # ... plus the depth unit and the plane fit's own error near the seed
SMOOTH_CELLS = 7  # surfaces are told apart on the depth averaged over this many cells square ...
SMOOTH_NOISE = min(1.0, D415.correlation_px / SMOOTH_CELLS)  # ... whose noise that averaging divides by the number
# of independent matches it spans along a side (the D415's noise is correlated over its matching window)


@dataclass(frozen=True)
class PlaneFrame:
    """A plane's frame in the robot base frame (see the module docstring)."""

    origin: np.ndarray
    normal: np.ndarray
    right: np.ndarray
    up: np.ndarray

    @classmethod
    def facing(cls, origin: np.ndarray, normal: np.ndarray, viewpoint: np.ndarray) -> PlaneFrame:
        """The frame of the plane through `origin` with `normal` turned toward `viewpoint`."""
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        if (np.asarray(viewpoint, float) - origin) @ n < 0:
            n = -n
        right = np.cross(UP, n)
        right /= np.linalg.norm(right)
        return cls(np.asarray(origin, float), n, right, np.cross(n, right))

    def point(self, s: np.ndarray | float, z: np.ndarray | float, offset: np.ndarray | float = 0.0) -> np.ndarray:
        """Base-frame points at plane coordinates (s, z) and `offset` along the normal."""
        s, z, offset = np.broadcast_arrays(*(np.asarray(v, float) for v in (s, z, offset)))
        return (self.origin + s[..., None] * self.right + z[..., None] * self.up
                + offset[..., None] * self.normal)

    def coordinates(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) plane coordinates (s, z, offset) of base-frame points."""
        d = np.asarray(points, float).reshape(-1, 3) - self.origin
        return np.stack([d @ self.right, d @ self.up, d @ self.normal], axis=1)


@dataclass(frozen=True)
class PlaneView:
    """The rectified view of a plane (see the module docstring); arrays are (rows, cols)."""

    plane: PlaneFrame
    res_m: float
    s_min: float
    z_max: float
    color: np.ndarray  # (rows, cols, 3) uint8 RGB
    gray: np.ndarray  # float32, 0-1
    seen: np.ndarray  # inside the image and not the arm
    offset_m: np.ndarray  # float32, NaN where there is no depth
    smooth_m: np.ndarray  # float32, the offset averaged over SMOOTH_CELLS (NaN where a cell has no depth)
    depth_m: np.ndarray  # float32, the measured depth seen in each cell (0: none)
    tolerance_m: np.ndarray  # float32: the D415's noise there (NOISE_SIGMAS) plus QUANTUM_M, for `smooth_m`
    map_uv: np.ndarray  # (rows, cols, 2) float32 image coordinates of each cell

    @property
    def shape(self) -> tuple[int, int]:
        return self.gray.shape

    def col(self, s: np.ndarray | float) -> np.ndarray:
        return np.round((np.asarray(s, float) - self.s_min) / self.res_m).astype(int)

    def row(self, z: np.ndarray | float) -> np.ndarray:
        return np.round((self.z_max - np.asarray(z, float)) / self.res_m).astype(int)

    def s(self, col: np.ndarray | float) -> np.ndarray:
        return self.s_min + np.asarray(col, float) * self.res_m

    def z(self, row: np.ndarray | float) -> np.ndarray:
        return self.z_max - np.asarray(row, float) * self.res_m

    def points(self, rows: np.ndarray, cols: np.ndarray, camera_to_base: np.ndarray, K: np.ndarray) -> np.ndarray:
        """(N, 3) plane coordinates (s, z, offset) of the measured points seen in cells (rows, cols) (with depth)."""
        uv = self.map_uv[rows, cols]
        depth = self.depth_m[rows, cols].astype(float)
        cam = np.stack([(uv[:, 0] - K[0, 2]) / K[0, 0] * depth, (uv[:, 1] - K[1, 2]) / K[1, 1] * depth, depth], 1)
        return self.plane.coordinates(cam @ camera_to_base[:3, :3].T + camera_to_base[:3, 3])

    @cached_property
    def lab(self) -> np.ndarray:
        """(rows, cols, 3) float32 colour in OpenCV's 8-bit Lab scale."""
        return cv2.cvtColor(self.color, cv2.COLOR_RGB2LAB).astype(np.float32)

    @cached_property
    def on_plane(self) -> np.ndarray:
        """Cells whose depth lies on the plane within the sensor's noise."""
        with np.errstate(invalid="ignore"):
            return self.seen & (np.abs(self.smooth_m) <= self.tolerance_m)

    @cached_property
    def in_front(self) -> np.ndarray:
        """Cells whose depth lies nearer the camera than the plane, beyond the noise."""
        with np.errstate(invalid="ignore"):
            return self.seen & (self.smooth_m > self.tolerance_m)

    @cached_property
    def behind(self) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            return self.seen & (self.smooth_m < -self.tolerance_m)

    @cached_property
    def no_depth(self) -> np.ndarray:
        return self.seen & np.isnan(self.offset_m)


def image_to_camera(frame: Frame) -> np.ndarray:
    """4x4 transform from the base frame to the camera frame."""
    return np.linalg.inv(np.asarray(frame.T_base_camera, float))


def rectify(frame: Frame, robot: np.ndarray, plane: PlaneFrame, s_range: tuple[float, float],
            z_range: tuple[float, float], res_m: float) -> PlaneView:
    """The rectified view of `plane` over s in `s_range`, z in `z_range` (m), one cell per `res_m`; `robot` the
    arm's pixels (seen as nothing)."""
    h, w = frame.depth_m.shape
    cols = max(int(np.ceil((s_range[1] - s_range[0]) / res_m)), 1)
    rows = max(int(np.ceil((z_range[1] - z_range[0]) / res_m)), 1)
    s = (s_range[0] + np.arange(cols) * res_m).astype(np.float32)
    z = (z_range[1] - np.arange(rows) * res_m).astype(np.float32)
    T = image_to_camera(frame)
    K = frame.intrinsics
    # camera coordinates of every cell, built from the plane's axes in the camera frame (no (rows, cols, 3) temporaries
    # beyond the three coordinates)
    o, r, u = T[:3, :3] @ plane.origin + T[:3, 3], T[:3, :3] @ plane.right, T[:3, :3] @ plane.up
    cam = [np.float32(o[i]) + s[None, :] * np.float32(r[i]) + z[:, None] * np.float32(u[i]) for i in range(3)]
    zc = np.maximum(cam[2], 1e-6)
    map_u = (cam[0] / zc * K.fx + K.cx).astype(np.float32)
    map_v = (cam[1] / zc * K.fy + K.cy).astype(np.float32)
    ahead = cam[2] > 0.05
    inside = ahead & (map_u >= 0) & (map_u <= w - 1) & (map_v >= 0) & (map_v <= h - 1)
    nearest = dict(interpolation=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    robot_here = cv2.remap(robot.astype(np.uint8), map_u, map_v, **nearest).astype(bool)
    seen = inside & ~robot_here
    color = cv2.remap(np.ascontiguousarray(frame.color), map_u, map_v, cv2.INTER_LINEAR)
    gray = cv2.cvtColor(color, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255
    depth = cv2.remap(np.asarray(frame.depth_m, np.float32), map_u, map_v, **nearest)
    with np.errstate(invalid="ignore", divide="ignore"):
        n_cam = T[:3, :3] @ plane.normal
        along = np.abs(np.float32(n_cam[0] / K.fx) * (map_u - np.float32(K.cx))
                       + np.float32(n_cam[1] / K.fy) * (map_v - np.float32(K.cy)) + np.float32(n_cam[2]))  # |n . ray|
        offset = np.where(seen & (depth > 0), (zc - depth) * along, np.nan).astype(np.float32)
        noise = np.float32(NOISE_SIGMAS * SMOOTH_NOISE * D415.subpixel / (K.fx * D415.baseline_m))  # sigma_z / z^2
        tolerance = noise * zc * zc * along + np.float32(QUANTUM_M)
        valid = (~np.isnan(offset)).astype(np.float32)
        box = dict(ksize=(SMOOTH_CELLS, SMOOTH_CELLS), normalize=False, borderType=cv2.BORDER_CONSTANT)
        smooth = cv2.boxFilter(np.nan_to_num(offset), -1, **box) / cv2.boxFilter(valid, -1, **box)
        smooth[np.isnan(offset)] = np.nan
    return PlaneView(plane, res_m, float(s_range[0]), float(z_range[1]), color, gray, seen, offset, smooth,
                     np.where(seen, depth, 0.0).astype(np.float32), tolerance, np.stack([map_u, map_v], axis=-1))
