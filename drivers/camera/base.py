"""The camera protocol: `read()` returns an aligned colour + metric depth `Frame`."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

DISTORTIONS = ("none", "brown_conrady", "inverse_brown_conrady", "modified_brown_conrady")
"""Lens models of `Intrinsics.distortion`, named as librealsense names them. The three Brown-Conrady variants take
the same five coefficients (k1, k2, p1, p2, k3), which librealsense applies as OpenCV's distortion model: a point
projects through the polynomial, a pixel deprojects by inverting it."""


@dataclass(frozen=True)
class Intrinsics:
    """Intrinsics of the (depth-aligned) colour image, in pixels: the pinhole (fx, fy, cx, cy) and the lens's
    `distortion` model (one of DISTORTIONS) with its `coeffs` (k1, k2, p1, p2, k3)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: str = "none"
    coeffs: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.distortion not in DISTORTIONS:
            raise ValueError(f"unknown lens distortion model {self.distortion!r}; expected one of "
                             f"{', '.join(DISTORTIONS)}")
        if len(self.coeffs) != 5:
            raise ValueError(f"distortion coefficients must be 5 numbers (k1, k2, p1, p2, k3), got {self.coeffs}")

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray | None:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3) of a lens with distortion; None for a pinhole camera
        (no model, or all coefficients zero)."""
        if self.distortion == "none" or not any(self.coeffs):
            return None
        return np.array(self.coeffs, float)

    def to_dict(self) -> dict:
        """The six pinhole fields, and `distortion` and `coeffs` for a lens with a model (not "none")."""
        pinhole = {k: getattr(self, k) for k in ("width", "height", "fx", "fy", "cx", "cy")}
        if self.distortion == "none":
            return pinhole
        return {**pinhole, "distortion": self.distortion, "coeffs": list(self.coeffs)}

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> Intrinsics:
        """Square pixels, principal point at the image centre, horizontal field of view `hfov_deg`."""
        f = (width / 2) / np.tan(np.radians(hfov_deg) / 2)
        return cls(width, height, float(f), float(f), (width - 1) / 2, (height - 1) / 2)


class SegLabel(IntEnum):
    """Labels of `Frame.segmentation` (simulation oracle only)."""

    BACKGROUND = 0
    OBJECT = 1
    HANDLE = 2
    ROBOT = 3


@dataclass
class Frame:
    """One aligned RGB-D frame.

    color: (H, W, 3) uint8 RGB; depth_m: (H, W) float32 metres, 0 where invalid; t: seconds since the
    stream started; T_base_camera: 4x4 pose of the camera in the robot base frame (None if unknown);
    segmentation: (H, W) uint8 `SegLabel`s, only from simulation; mask: (H, W) bool object mask when
    a recording stores one.
    """

    index: int
    t: float
    color: np.ndarray
    depth_m: np.ndarray
    intrinsics: Intrinsics
    T_base_camera: np.ndarray | None = None
    segmentation: np.ndarray | None = None
    mask: np.ndarray | None = None


class Camera(ABC):
    """Base class of every camera. Use as a context manager: `with camera: frame = camera.read()`.

    Every camera implements `intrinsics` and `read`; the other capabilities have defaults, so that no caller asks
    a camera what it is: `serial` (the device's serial number, which names its calibration files; None for what
    is not a device), `depth_scale` (metres per unit of its 16-bit depth: what a depth PNG of it stores) and
    `min_range_m` (the nearest depth it measures at its current resolution, which perception drops below; None
    when it does not say).
    """

    serial: str | None = None
    depth_scale: float = 0.001
    min_range_m: float | None = None

    @property
    @abstractmethod
    def intrinsics(self) -> Intrinsics: ...

    def connect(self) -> None:
        """Open the device or file (idempotent)."""

    def disconnect(self) -> None:
        """Release the device or file (idempotent, safe after a failure)."""

    @abstractmethod
    def read(self, timeout_s: float = 2.0) -> Frame:
        """The next frame; raises CameraError on timeout and RecordingError at the end of a recording."""

    def __enter__(self) -> Camera:
        self.connect()
        return self

    def __exit__(self, *exc) -> None:
        self.disconnect()
