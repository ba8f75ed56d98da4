"""The `classical` segmenter (no weights): a colour/depth region cut from a box, then propagated frame to frame.

First frame: GrabCut inside the given box (colour), kept to the object's depth band; it fixes a colour model
(object vs surroundings histograms) and the depth band. Later frames: pixels near the previous mask (a
dilation of `search_px`) that the colour model calls object and that lie in the depth band; connected parts
touching the previous mask are kept and enclosed holes (the handle) filled. Works when the object's colours
differ from its surroundings and the arm's; see docs/perception.md for its limits.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from deploy.errors import PerceptionError
from deploy.perception.base import Pointer, Segmenter
from deploy.perception.config import PerceptionConfig
from deploy.perception.track_health import box_of, track_lost
from drivers.camera.base import Frame

log = logging.getLogger(__name__)

_BINS = 16  # colour histogram bins per channel
_SHIFT = 4  # 256 / _BINS = 2**_SHIFT
BACKGROUND_BORDER_PX = 8  # GrabCut's background band when a box leaves none


def _clip_box(box: tuple[float, float, float, float], w: int, h: int) -> tuple[int, int, int, int]:
    x0, y0, x1, y1 = (int(round(v)) for v in box)
    x0, x1 = max(0, min(x0, x1)), min(w, max(x0, x1))
    y0, y1 = max(0, min(y0, y1)), min(h, max(y0, y1))
    return x0, y0, x1, y1


def colour_index(color: np.ndarray) -> np.ndarray:
    """Per-pixel histogram bin (0 .. _BINS^3 - 1) of an RGB uint8 image."""
    q = color >> _SHIFT
    return (q[..., 0].astype(np.int32) << (2 * _SHIFT)) | (q[..., 1].astype(np.int32) << _SHIFT) | q[..., 2]


class ColourModel:
    """Object-vs-surroundings colour histograms (_BINS^3 bins), blended over frames as shading changes.

    `lut[bin]` is True for colours more likely object than surroundings, and for colours never seen in
    the surroundings within `spread_bins` of an object colour (a turning door darkens gradually).
    """

    def __init__(self, spread_bins: int = 2):
        self.spread_bins = spread_bins
        self.p_in = np.zeros(_BINS**3)
        self.p_out = np.zeros(_BINS**3)
        self.lut = np.zeros(_BINS**3, bool)

    def update(self, index: np.ndarray, inside: np.ndarray, outside: np.ndarray, rate: float = 1.0) -> None:
        """Blend in the colours (`colour_index` bins) of `inside` (object) and `outside` (surroundings) pixels
        with weight `rate`."""
        from scipy.ndimage import binary_dilation

        for hist, where in ((self.p_in, inside), (self.p_out, outside)):
            count = np.count_nonzero(where)
            if count:
                hist *= 1.0 - rate
                hist += rate * np.bincount(index[where], minlength=_BINS**3) / count
        objectish = (self.p_in > self.p_out).reshape(_BINS, _BINS, _BINS)
        near = binary_dilation(objectish, iterations=self.spread_bins) if self.spread_bins else objectish
        self.lut = (objectish | (near & (self.p_out == 0).reshape(objectish.shape))).ravel()

    def __call__(self, index: np.ndarray) -> np.ndarray:
        """Per-pixel bool from `colour_index` bins: the colour is the object's."""
        return self.lut[index]


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """`mask` with every region it fully encloses filled in."""
    padded = np.pad(mask, 1).astype(np.uint8)
    flood = padded.copy()
    cv2.floodFill(flood, None, (0, 0), 1)
    return (padded | (1 - flood)).astype(bool)[1:-1, 1:-1]


def keep_touching(mask: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The connected parts of `mask` that overlap `previous`."""
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return mask
    touching = np.bincount((labels * (previous & mask)).ravel(), minlength=count) > 0
    touching[0] = False
    return touching[labels]


def grabcut_in_box(color: np.ndarray, box: tuple[int, int, int, int], iterations: int = 3) -> np.ndarray:
    """GrabCut foreground of the RGB image inside `box` (x0, y0, x1, y1); computed on a crop around it. GrabCut
    learns the background from the pixels outside the box: a box that leaves none (the whole image) is inset by
    BACKGROUND_BORDER_PX."""
    h, w = color.shape[:2]
    x0, y0, x1, y1 = box
    if x0 <= 0 and y0 <= 0 and x1 >= w and y1 >= h:
        b = min(BACKGROUND_BORDER_PX, w // 4, h // 4)
        x0, y0, x1, y1 = b, b, w - b, h - b
    mx, my = max(8, (x1 - x0) // 5), max(8, (y1 - y0) // 5)
    cx0, cy0, cx1, cy1 = max(0, x0 - mx), max(0, y0 - my), min(w, x1 + mx), min(h, y1 + my)
    crop = cv2.cvtColor(np.ascontiguousarray(color[cy0:cy1, cx0:cx1]), cv2.COLOR_RGB2BGR)
    mask = np.zeros((h, w), bool)
    if crop.size == 0 or float(crop.std()) < 2.0:  # a blank view (covered lens): nothing to cut, and GrabCut stalls
        return mask
    labels = np.zeros(crop.shape[:2], np.uint8)
    rect = (x0 - cx0, y0 - cy0, max(1, x1 - x0), max(1, y1 - y0))
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(crop, labels, rect, bgd, fgd, iterations, cv2.GC_INIT_WITH_RECT)
    mask[cy0:cy1, cx0:cx1] = (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
    return mask


class ClassicalSegmenter(Segmenter):
    """Box-initialised colour/depth region tracking; needs `config.box` (or `box`) on the first frame."""

    name = "classical"

    def __init__(self, config: PerceptionConfig | None = None, search_px: int = 24, depth_margin_m: float = 0.25,
                 adapt_rate: float = 0.3):
        self.config = config or PerceptionConfig()
        if self.config.box is None:
            raise PerceptionError(
                "the classical segmenter needs the object's box on the first frame: pass --box X0 Y0 X1 Y1 "
                "(pixels) or set `box` in the perception config"
            )
        self.search_px = search_px
        self.depth_margin_m = depth_margin_m
        self.adapt_rate = adapt_rate
        self.redetections = 0
        self._kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * search_px + 1, 2 * search_px + 1))
        self._colour = ColourModel()
        self._depth_band = (0.0, np.inf)
        self._good: np.ndarray | None = None
        self._reference_area = 0

    def start(self, frame: Frame, prompt: str | None = None, pointer: Pointer | None = None) -> np.ndarray:
        """The object in the configured box on the first frame (`prompt` and `pointer` are not used: the box says
        where it is)."""
        h, w = frame.color.shape[:2]
        box = _clip_box(self.config.box, w, h)
        if box[2] - box[0] < 4 or box[3] - box[1] < 4:
            raise PerceptionError(f"box {self.config.box} is empty or outside the {w}x{h} image: give a box "
                                  "X0 Y0 X1 Y1 around the object, in pixels")
        mask = self._segment_box(frame, box)
        self._reference_area = int(np.count_nonzero(mask))
        if self._reference_area == 0:
            raise PerceptionError(f"no object found in box {box} on frame {frame.index}: the box holds no region "
                                  "distinct from its surroundings; draw a tighter box around the object")
        self._good, self.redetections = mask, 0
        log.info("classical: object in box %s px on frame %d: %d pixels", box, frame.index, self._reference_area)
        return mask

    def _segment_box(self, frame: Frame, box: tuple[int, int, int, int]) -> np.ndarray:
        """GrabCut in the box, kept to the object's depth band; sets the colour model and the band."""
        mask = grabcut_in_box(frame.color, box)
        depth = frame.depth_m
        valid = mask & (depth > 0)
        if np.count_nonzero(valid) >= 20:
            lo, hi = np.percentile(depth[valid], [2, 98])
            self._depth_band = (max(0.0, lo - self.depth_margin_m), hi + self.depth_margin_m)
            mask &= (depth == 0) | ((depth >= self._depth_band[0]) & (depth <= self._depth_band[1]))
        mask = fill_holes(mask)
        self._colour = ColourModel()
        self._colour.update(colour_index(frame.color), mask, ~mask)
        return mask

    def track(self, frame: Frame) -> np.ndarray:
        if self._good is None:
            raise PerceptionError("classical: track() called before start(); call start on the first frame")
        mask = self._propagate(frame, self._good)
        reason = track_lost(mask, self._good, self._reference_area, self.config.min_area_ratio, self.config.min_iou)
        if reason is not None:
            mask = self._recover(frame, reason)
        self._good = mask
        return mask

    def _propagate(self, frame: Frame, previous: np.ndarray) -> np.ndarray:
        """The object's mask on `frame` from its mask on the frame before."""
        box = box_of(cv2.dilate(previous.astype(np.uint8), self._kernel).astype(bool))
        mask = np.zeros(previous.shape, bool)
        if box is None:
            return mask
        x0, y0, x1, y1 = (int(v) for v in box)
        roi = np.s_[y0:y1, x0:x1]
        search = cv2.dilate(previous[roi].astype(np.uint8), self._kernel).astype(bool)
        depth = frame.depth_m[roi]
        in_band = (depth == 0) | ((depth >= self._depth_band[0]) & (depth <= self._depth_band[1]))
        index = colour_index(frame.color[roi])
        candidate = search & in_band & self._colour(index)
        candidate = cv2.morphologyEx(candidate.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        mask[roi] = fill_holes(keep_touching(candidate.astype(bool), previous[roi]))
        self._colour.update(index, mask[roi], search & ~mask[roi], self.adapt_rate)
        return mask

    def _recover(self, frame: Frame, reason: str) -> np.ndarray:
        """Cut the object again in the last good mask's box; stop after `max_redetections` attempts."""
        h, w = frame.color.shape[:2]
        x0, y0, x1, y1 = box_of(self._good) or (0, 0, w, h)
        for attempt in range(1, self.config.max_redetections + 1):
            self.redetections += 1
            mask = grabcut_in_box(frame.color, _clip_box((x0 - 8, y0 - 8, x1 + 8, y1 + 8), w, h))
            mask = fill_holes(mask & ((frame.depth_m == 0) | ((frame.depth_m >= self._depth_band[0])
                                                             & (frame.depth_m <= self._depth_band[1]))))
            if track_lost(mask, self._good, self._reference_area, self.config.min_area_ratio, 0.0) is None:
                return mask
            reason = f"{reason}; re-segmentation {attempt} found no plausible region"
        raise PerceptionError(
            f"classical segmenter lost the object at frame {frame.index}: {reason}; stopped after "
            f"{self.config.max_redetections} re-segmentation(s). Keep the object in view and unoccluded, "
            "give a tighter --box, or use the gdino-sam2 segmenter"
        )


def open_classical(_argument: str, config: PerceptionConfig) -> ClassicalSegmenter:
    return ClassicalSegmenter(config)
