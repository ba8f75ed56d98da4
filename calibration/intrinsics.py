"""Camera intrinsics from board views (`cv2.calibrateCameraExtended`), for users who do not trust factory values.

The model is what a few board views can pin down: fx, fy, cx, cy, and the radial terms k1, k2 only when the
corners cover enough of the image (k3 and the tangential p1, p2 stay zero: on views near the image centre they
absorb noise, e.g. k3 = -52, and drag the focal length with them). A fit replaces the factory values only when
it is precise, plausible and significantly different from them (`compare_with_factory`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.detect import BoardView
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

MIN_VIEWS = 4
MAX_VIEW_RMS_PX = 1.0  # a view worse than this is a misdetection or a blurred image
MAX_FOCAL_STD = 0.005  # the views must fix fx and fy to this share (1 sigma): 0.5 % is 2.5 mm of depth at 0.5 m
MAX_CENTRE_STD = 0.01  # ... and cx, cy to this share of the image width, height
MAX_FACTORY_OFFSET = 0.02  # fx, fy (relative) and cx, cy (share of width, height) this far from factory: refused
DISTORTION_COVERAGE = 0.5  # share of the image the corners must cover before k1, k2 are fitted
SIGNIFICANT_SIGMAS = 3.0  # a fit closer than this to the factory values confirms them


@dataclass(frozen=True)
class IntrinsicsResult:
    """Pinhole intrinsics, distortion (k1, k2, p1, p2, k3), RMS reprojection error (px), views used, the standard
    deviations of fx, fy, cx, cy, k1, k2 (px; 0 where not fitted), each view's RMS error (px) and the share of
    the image the corners cover."""

    intrinsics: Intrinsics
    distortion: np.ndarray
    rms_px: float
    views: int
    std: np.ndarray
    view_rms_px: np.ndarray
    coverage: float


def coverage(views: Sequence[BoardView], width: int, height: int) -> float:
    """Share of the image inside the convex hull of every view's corners."""
    hull = cv2.convexHull(np.vstack([v.pixels for v in views]).astype(np.float32))
    return float(cv2.contourArea(hull)) / (width * height)


def calibrate_intrinsics(
    views: Sequence[BoardView], width: int, height: int, initial: Intrinsics | None = None
) -> IntrinsicsResult:
    """Fit fx, fy, cx, cy (and k1, k2 when the views cover DISTORTION_COVERAGE of the image) to board views of a
    `width` x `height` image. `initial` (e.g. the factory values) seeds the fit; without it OpenCV's planar
    initialisation is used. Views must show the board tilted in several directions."""
    if len(views) < MIN_VIEWS:
        raise CalibrationError(
            f"intrinsics need at least {MIN_VIEWS} board views, got {len(views)}: take more views with the "
            "board tilted in different directions, filling the image"
        )
    obj = [v.points.astype(np.float32) for v in views]
    img = [v.pixels.astype(np.float32) for v in views]
    covered = coverage(views, width, height)
    flags = cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if covered < DISTORTION_COVERAGE:
        flags |= cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2
    K0 = None
    if initial is not None:
        flags, K0 = flags | cv2.CALIB_USE_INTRINSIC_GUESS, initial.K.copy()
    rms, K, dist, _, _, std, _, per_view = cv2.calibrateCameraExtended(obj, img, (width, height), K0, np.zeros(5),
                                                                      flags=flags)
    if not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise CalibrationError("intrinsics fit diverged: take views with the board tilted by 20-40 deg")
    fitted = Intrinsics(width, height, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    return IntrinsicsResult(fitted, dist.ravel()[:5], float(rms), len(views), std.ravel()[:6], per_view.ravel(),
                            covered)


def factory_offset(intrinsics: Intrinsics, factory: Intrinsics) -> str | None:
    """What of `intrinsics` is more than MAX_FACTORY_OFFSET from the factory values (e.g. "fx 490.8 vs 502.3"),
    None when all are within it."""
    if (intrinsics.width, intrinsics.height) != (factory.width, factory.height):
        return f"image {intrinsics.width}x{intrinsics.height} vs {factory.width}x{factory.height}"
    scale = {"fx": factory.fx, "fy": factory.fy, "cx": factory.width, "cy": factory.height}
    off = [f"{k} {getattr(intrinsics, k):.1f} vs {getattr(factory, k):.1f}" for k, s in scale.items()
           if abs(getattr(intrinsics, k) - getattr(factory, k)) > MAX_FACTORY_OFFSET * s]
    return ", ".join(off) or None


def compare_with_factory(result: IntrinsicsResult, factory: Intrinsics) -> bool:
    """True when the fit should replace the factory values: it differs from them by more than SIGNIFICANT_SIGMAS.
    False when it confirms them. CalibrationError when it is unreliable (a bad view, too imprecise) or
    implausibly far from them."""
    worst = int(np.argmax(result.view_rms_px))
    if result.view_rms_px[worst] > MAX_VIEW_RMS_PX:
        raise CalibrationError(
            f"intrinsics not saved: view {worst + 1} of {result.views} has a reprojection error of "
            f"{result.view_rms_px[worst]:.2f} px (limit {MAX_VIEW_RMS_PX:g}), a misdetection or a blurred image: "
            "light the board evenly, keep it still and run again")
    fit = result.intrinsics
    std = dict(zip(("fx", "fy", "cx", "cy"), result.std[:4], strict=True))
    limits = {"fx": MAX_FOCAL_STD * fit.fx, "fy": MAX_FOCAL_STD * fit.fy, "cx": MAX_CENTRE_STD * fit.width,
              "cy": MAX_CENTRE_STD * fit.height}
    loose = [k for k in limits if std[k] > limits[k]]
    if loose:
        k = loose[0]
        raise CalibrationError(
            f"intrinsics not saved: {result.views} views fix {k} only to +-{std[k]:.1f} px (limit "
            f"{limits[k]:.1f} px), too loosely to improve on the factory values; the board covered "
            f"{result.coverage:.0%} of the image: bring it closer, use larger tilts and more --poses")
    offset = factory_offset(fit, factory)
    if offset:
        raise CalibrationError(
            f"intrinsics not saved: {offset} differ from the camera's factory values by more than "
            f"{MAX_FACTORY_OFFSET:.0%}: check the board detection and that the camera streams its factory "
            "resolution")
    factory_values = np.array([factory.fx, factory.fy, factory.cx, factory.cy, 0.0, 0.0])
    values = np.array([fit.fx, fit.fy, fit.cx, fit.cy, *result.distortion[:2]])
    fitted = result.std > 0
    return bool(np.any(np.abs(values - factory_values)[fitted] > SIGNIFICANT_SIGMAS * result.std[fitted]))
