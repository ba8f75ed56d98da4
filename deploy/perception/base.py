"""The segmenter protocol: the object's mask on the first frame from a text prompt and what the user pointed at,
then tracked."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from drivers.camera.base import Frame


@dataclass(frozen=True)
class Pointer:
    """What the user showed of the part to open: the pixel (u: column, v: row) they pointed at on it in the first
    frame (`deploy open* --point U V`; in simulation the simulated user's)."""

    u: float
    v: float

    @classmethod
    def of(cls, point: tuple[float, float] | None) -> Pointer | None:
        return None if point is None else cls(float(point[0]), float(point[1]))

    def inside(self, width: int, height: int) -> bool:
        """Whether the pixel lies on a width x height image."""
        return 0 <= self.u < width and 0 <= self.v < height

    def pixel(self) -> tuple[int, int]:
        """(row, column) of the pixel."""
        return int(self.v), int(self.u)


class Segmenter(ABC):
    """Segments the object to open: `start` on the first frame, `track` on every later one.

    Masks are (H, W) bool arrays aligned with the frame's depth. `redetections` counts how often the backend had to
    find a lost object again (0 for backends that never do).
    """

    name: str
    redetections: int = 0

    @abstractmethod
    def start(self, frame: Frame, prompt: str = "cabinet", pointer: Pointer | None = None) -> np.ndarray:
        """Find the object named by `prompt` on the first frame, the one with the part `pointer` shows when given
        (a backend that cannot use it says so in its docstring); its mask."""

    @abstractmethod
    def track(self, frame: Frame) -> np.ndarray:
        """The object's mask on a later frame."""

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        """The handle's mask when the backend can tell it apart, else None (the handle is then found in
        the cloud as the points protruding from the front)."""
        return None
