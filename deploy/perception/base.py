"""The segmenter protocol: the object's mask on the first frame from a text prompt and what the user pointed at,
then tracked."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from drivers.camera.base import Frame


@dataclass(frozen=True)
class Pointer:
    """What the user showed of the part to open in the first frame: the pixel (u: column, v: row) they pointed at on
    its front (`deploy open* --point U V`; in simulation the simulated user's), and/or a `box` (x0, y0, x1, y1) around
    it (`--box`); a pointer given by its box alone has the box's centre as its pixel."""

    u: float
    v: float
    box: tuple[float, float, float, float] | None = None

    @classmethod
    def of(cls, point: tuple[float, float] | None,
           box: tuple[float, float, float, float] | None = None) -> Pointer | None:
        """The pointer of a `point` and / or a `box` (None when neither is given)."""
        box = None if box is None else tuple(float(b) for b in box)  # type: ignore[assignment]
        if point is not None:
            return cls(float(point[0]), float(point[1]), box)
        if box is not None:
            return cls((box[0] + box[2]) / 2, (box[1] + box[3]) / 2, box)
        return None

    def inside(self, width: int, height: int) -> bool:
        """Whether the pixel lies on a width x height image."""
        return 0 <= self.u < width and 0 <= self.v < height

    def pixel(self) -> tuple[int, int]:
        """(row, column) of the pixel."""
        return int(self.v), int(self.u)

    def __str__(self) -> str:
        """The option that gave it, as the user typed it."""
        if self.box is None:
            return f"--point {self.u:g} {self.v:g}"
        return "--box " + " ".join(f"{b:g}" for b in self.box)


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
