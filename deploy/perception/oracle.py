"""The oracle segmenter: ground-truth masks, from the simulator's labels or a recording's stored masks."""

from __future__ import annotations

import numpy as np

from deploy.errors import PerceptionError
from deploy.perception.base import Pointer, Segmenter
from drivers.camera.base import Frame, SegLabel


class OracleSegmenter(Segmenter):
    """Masks read from `frame.segmentation` (object = OBJECT | HANDLE, handle = HANDLE), or a recording's
    `frame.mask` (object only; the handle is then found in the cloud)."""

    name = "oracle"

    def start(self, frame: Frame, prompt: str = "cabinet", pointer: Pointer | None = None) -> np.ndarray:
        """The labelled object (the prompt and pointer are not used: the labels name it)."""
        return self.track(frame)

    def track(self, frame: Frame) -> np.ndarray:
        if frame.segmentation is None and frame.mask is not None:
            return np.asarray(frame.mask, bool)
        labels = _labels(frame)
        return (labels == SegLabel.OBJECT) | (labels == SegLabel.HANDLE)

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        if frame.segmentation is None and frame.mask is not None:
            return None
        return _labels(frame) == SegLabel.HANDLE


def _labels(frame: Frame) -> np.ndarray:
    if frame.segmentation is None:
        raise PerceptionError(
            f"frame {frame.index} has no segmentation labels or stored mask: the oracle segmenter needs the "
            "simulation (--camera sim) or a recording with masks; otherwise use gdino-sam2 or classical"
        )
    return np.asarray(frame.segmentation)


def open_oracle(_argument: str, _config: object) -> OracleSegmenter:
    return OracleSegmenter()
