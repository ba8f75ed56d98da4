"""The segmenter protocol: the object's mask on the first frame from a text prompt, then tracked."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from drivers.camera.base import Frame


class Segmenter(ABC):
    """Segments the object to open: `start` on the first frame, `track` on every later one.

    Masks are (H, W) bool arrays aligned with the frame's depth. `redetections` counts how often the backend had to
    find a lost object again (0 for backends that never do).
    """

    name: str
    redetections: int = 0

    @abstractmethod
    def start(self, frame: Frame, prompt: str = "cabinet") -> np.ndarray:
        """Find the object named by `prompt` on the first frame; its mask."""

    @abstractmethod
    def track(self, frame: Frame) -> np.ndarray:
        """The object's mask on a later frame."""

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        """The handle's mask when the backend can tell it apart, else None (the handle is then found in
        the cloud as the points protruding from the front)."""
        return None
