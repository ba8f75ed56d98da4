"""The `gdino-sam2` segmenter: Grounding DINO finds the object (and its handle) once, SAM2 tracks them online.

When the track collapses (area or IoU, see `track_health`) the object is re-detected and the tracker
re-prompted on the current frame; after `max_redetections` failed attempts on one frame tracking stops with a
`PerceptionError` rather than hand the controller a wrong mask.
"""

from __future__ import annotations

import logging

import numpy as np

from deploy.errors import PerceptionError
from deploy.perception.base import Pointer, Segmenter
from deploy.perception.config import PerceptionConfig
from deploy.perception.gdino import GroundingDinoDetector
from deploy.perception.sam2_video import Box, StreamingTracker
from deploy.perception.track_health import box_iou, box_of, track_lost
from drivers.camera.base import Frame

log = logging.getLogger(__name__)

OBJECT_ID, HANDLE_ID = 1, 2


class GdinoSam2Segmenter(Segmenter):
    """Detector (optional when `config.box` is given) + streaming tracker behind the Segmenter protocol."""

    name = "gdino-sam2"

    def __init__(self, tracker: StreamingTracker, detector: GroundingDinoDetector | None,
                 config: PerceptionConfig | None = None):
        self.tracker = tracker
        self.detector = detector
        self.config = config or PerceptionConfig()
        self.prompt = self.config.object_prompt
        self.redetections = 0
        self._reference_area = 0
        self._good: np.ndarray | None = None
        self._handle: np.ndarray | None = None

    @classmethod
    def from_config(cls, config: PerceptionConfig) -> GdinoSam2Segmenter:
        """Load the models named by `config` on its device (the detector only if it can be needed)."""
        from deploy.perception.device import choose_device
        from deploy.perception.models import load_detector, load_tracker

        device, dtype = choose_device(config.device)
        tracker = StreamingTracker(*load_tracker(config.tracker, device, dtype))
        needs_detector = config.box is None or bool(config.handle_prompt)
        detector = None
        if needs_detector:
            detector = GroundingDinoDetector(*load_detector(config.detector, device, dtype),
                                             config.box_threshold, config.text_threshold)
        return cls(tracker, detector, config)

    def start(self, frame: Frame, prompt: str | None = None, pointer: Pointer | None = None) -> np.ndarray:
        """The object `prompt` names in the configured box, else the best detection (among those holding the
        `pointer`'s pixel, when any does), tracked from here."""
        self.prompt = prompt or self.config.object_prompt
        box = self.config.box or self._detect(frame, None, pointer)
        if box is None:
            raise PerceptionError(
                f"no {self.prompt!r} found on frame {frame.index} above box threshold {self.config.box_threshold}: "
                "check the camera sees the object, change --prompt, lower the threshold, or pass --box X0 Y0 X1 Y1"
            )
        masks = self._prompt(frame, box)
        log.info("gdino-sam2: %r at box %s px on frame %d (%s)%s", self.prompt, _fmt(box), frame.index,
                 "given --box" if self.config.box else "detected", ", handle too" if HANDLE_ID in masks else "")
        self._reference_area = int(np.count_nonzero(masks[OBJECT_ID]))
        if self._reference_area == 0:
            raise PerceptionError(
                f"the tracker returned an empty mask for {self.prompt!r} in box {_fmt(box)} on frame {frame.index}: "
                "check the box covers the object (pass a tighter --box) and the tracker checkpoint"
            )
        self._good, self.redetections = masks[OBJECT_ID], 0
        return masks[OBJECT_ID]

    def track(self, frame: Frame) -> np.ndarray:
        if self._good is None:
            raise PerceptionError("gdino-sam2: track() called before start(); call start on the first frame")
        masks = self.tracker.track(frame.color)
        mask = masks[OBJECT_ID]
        reason = track_lost(mask, self._good, self._reference_area, self.config.min_area_ratio, self.config.min_iou)
        if reason is not None:
            mask = self._recover(frame, reason)
        else:
            self._handle = masks.get(HANDLE_ID)
            self._good = mask
        return mask

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        return self._handle

    def _recover(self, frame: Frame, reason: str) -> np.ndarray:
        """Re-detect (or re-prompt with the last good box) on this frame; stop after too many failures."""
        last_box = box_of(self._good)
        for attempt in range(1, self.config.max_redetections + 1):
            self.redetections += 1
            box = (self._detect(frame, last_box) if self.detector is not None else None) or last_box
            masks = self._prompt(frame, box)
            if track_lost(masks[OBJECT_ID], self._good, self._reference_area, self.config.min_area_ratio, 0.0) is None:
                return masks[OBJECT_ID]
            reason = f"{reason}; re-detection {attempt} gave an implausible mask"
        raise PerceptionError(
            f"lost track of {self.prompt!r} at frame {frame.index}: {reason}; stopped after "
            f"{self.config.max_redetections} re-detection(s). Check the object is in view and not occluded, then "
            "restart (a tighter --box or a better prompt helps)"
        )

    def _prompt(self, frame: Frame, box: Box) -> dict[int, np.ndarray]:
        """(Re)start the tracker on `frame` with the object box and, if found inside it, the handle box."""
        boxes = {OBJECT_ID: box}
        if self.detector is not None and self.config.handle_prompt:
            handles = self.detector.detect(frame.color, self.config.handle_prompt, within=box)
            if handles:
                boxes[HANDLE_ID] = handles[0].box
        masks = self.tracker.start(frame.color, boxes)
        self._handle = masks.get(HANDLE_ID)
        return masks

    def _detect(self, frame: Frame, near: Box | None, pointer: Pointer | None = None) -> Box | None:
        """The best-scoring box of the object prompt (the best overlapping `near`, or holding `pointer`'s pixel,
        when given and any does)."""
        if self.detector is None:
            return None
        found = self.detector.detect(frame.color, self.prompt)
        if pointer is not None:
            found = [d for d in found if d.box[0] <= pointer.u <= d.box[2] and d.box[1] <= pointer.v <= d.box[3]] \
                or found
        if near is not None:
            overlapping = [d for d in found if box_iou(d.box, near) > 0.1]
            found = overlapping or found
        return found[0].box if found else None


def _fmt(box: Box) -> str:
    return "(" + ", ".join(f"{v:.0f}" for v in box) + ")"


def open_gdino_sam2(_argument: str, config: PerceptionConfig) -> GdinoSam2Segmenter:
    return GdinoSam2Segmenter.from_config(config)
