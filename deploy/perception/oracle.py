"""The oracle segmenter: the simulator's segmentation labels (simulation only)."""

from __future__ import annotations

import numpy as np

from deploy.errors import PerceptionError
from deploy.perception.base import Segmenter
from drivers.camera.base import Frame, SegLabel


class OracleSegmenter(Segmenter):
    """Masks read from `frame.segmentation`: object = OBJECT | HANDLE, handle = HANDLE."""

    name = "oracle"

    def start(self, frame: Frame, prompt: str = "cabinet") -> np.ndarray:
        return self.track(frame)

    def track(self, frame: Frame) -> np.ndarray:
        labels = _labels(frame)
        return (labels == SegLabel.OBJECT) | (labels == SegLabel.HANDLE)

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        return _labels(frame) == SegLabel.HANDLE


def _labels(frame: Frame) -> np.ndarray:
    if frame.segmentation is None:
        raise PerceptionError(
            f"frame {frame.index} has no segmentation labels: the oracle segmenter only works in simulation "
            "(--camera sim); with a real or recorded camera use a model-based segmenter"
        )
    return np.asarray(frame.segmentation)
