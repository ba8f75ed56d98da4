"""When a track counts as lost: the mask's area or its overlap with the previous mask collapses."""

from __future__ import annotations

import numpy as np


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two bool masks (1.0 when both are empty)."""
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def track_lost(mask: np.ndarray, previous: np.ndarray, reference_area: int, min_area_ratio: float,
               min_iou: float) -> str | None:
    """Why `mask` is not a credible continuation of `previous` (None if it is).

    reference_area: the pixel count of the first (detected) mask.
    """
    area = int(np.count_nonzero(mask))
    if area < min_area_ratio * reference_area:
        return f"mask area {area} px fell below {min_area_ratio:.2f} x the first mask's {reference_area} px"
    iou = mask_iou(mask, previous)
    if iou < min_iou:
        return f"IoU {iou:.2f} with the previous mask is below {min_iou:.2f}"
    return None


def box_of(mask: np.ndarray) -> tuple[float, float, float, float] | None:
    """The bounding box (x0, y0, x1, y1) of a bool mask in pixels, None if empty."""
    import cv2

    x, y, w, h = cv2.boundingRect(np.asarray(mask, np.uint8))
    if w == 0 or h == 0:
        return None
    return float(x), float(y), float(x + w), float(y + h)


def box_iou(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> float:
    """Intersection over union of two (x0, y0, x1, y1) boxes."""
    inter = max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0
