"""Camera intrinsics from board views (`cv2.calibrateCamera`), for users who do not trust factory values."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.detect import BoardView
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

MIN_VIEWS = 4


@dataclass(frozen=True)
class IntrinsicsResult:
    """Pinhole intrinsics, distortion (k1, k2, p1, p2, k3), RMS reprojection error (px) and views used."""

    intrinsics: Intrinsics
    distortion: np.ndarray
    rms_px: float
    views: int


def calibrate_intrinsics(
    views: Sequence[BoardView], width: int, height: int, initial: Intrinsics | None = None
) -> IntrinsicsResult:
    """Fit fx, fy, cx, cy and 5 distortion terms to board views of a `width` x `height` image.

    `initial` (e.g. the factory values) seeds the fit; without it OpenCV's planar initialisation is used.
    Views must show the board tilted in several directions: fronto-parallel views alone leave the focal
    length undetermined.
    """
    if len(views) < MIN_VIEWS:
        raise CalibrationError(
            f"intrinsics need at least {MIN_VIEWS} board views, got {len(views)}: take more views with the "
            "board tilted in different directions, filling the image"
        )
    obj = [v.points.astype(np.float32) for v in views]
    img = [v.pixels.astype(np.float32) for v in views]
    flags, K0 = 0, None
    if initial is not None:
        flags, K0 = cv2.CALIB_USE_INTRINSIC_GUESS, initial.K.copy()
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, (width, height), K0, None, flags=flags)
    if not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise CalibrationError("intrinsics fit diverged: take views with the board tilted by 20-40 deg")
    fitted = Intrinsics(width, height, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    return IntrinsicsResult(fitted, dist.ravel(), float(rms), len(views))
