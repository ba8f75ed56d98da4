"""A camera whose frames get their pose in the arm's base frame from a function (the hand-eye calibration)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from drivers.camera.base import Camera, Frame, Intrinsics


class PosedCamera(Camera):
    """Wraps `camera`: a frame that does not carry its `T_base_camera` (a recording may) gets it from `pose()`,
    read with the frame (an eye-in-hand camera's pose follows the arm); with `override`, every frame does (a
    calibration the user named replaces the poses a recording carries)."""

    def __init__(self, camera: Camera, pose: Callable[[], np.ndarray], override: bool = False) -> None:
        self.camera, self.pose, self.override = camera, pose, override

    @property
    def intrinsics(self) -> Intrinsics:
        return self.camera.intrinsics

    @property
    def serial(self) -> str | None:
        return self.camera.serial

    @property
    def depth_scale(self) -> float:
        return self.camera.depth_scale

    @property
    def min_range_m(self) -> float | None:
        return self.camera.min_range_m

    def connect(self) -> None:
        self.camera.connect()

    def disconnect(self) -> None:
        self.camera.disconnect()

    def read(self, timeout_s: float = 2.0) -> Frame:
        frame = self.camera.read(timeout_s)
        if self.override or frame.T_base_camera is None:
            frame.T_base_camera = self.pose()
        return frame
