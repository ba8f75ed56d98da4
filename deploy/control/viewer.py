"""`--view`: stream an episode to a rerun viewer (rerun-sdk, optional extra `axisloop[viewer]`).

Logged on the arm-time timeline: colour, depth and the object mask per frame, the gripper pose, the object
cloud of the first frame, the axis acted on at each step and the estimated opening. Everything is also
saved to RUN/episode.rrd (`rerun RUN/episode.rrd` replays it); a live viewer is spawned when a display is
available.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from deploy.errors import ConfigError
from deploy.geometry.types import Axis
from drivers.camera.base import Frame

AXIS_LENGTH_M = 0.6


class RerunViewer:
    """Logs to a rerun recording saved at `path`; `spawn` also opens a live viewer."""

    def __init__(self, path: Path, spawn: bool | None = None) -> None:
        try:
            import rerun as rr
        except ImportError as exc:
            raise ConfigError("--view needs the rerun viewer: pip install 'axisloop[viewer]' "
                              "(or run without --view)") from exc
        self.rr = rr
        self.rec = rr.RecordingStream("axisloop")
        if spawn if spawn is not None else _has_display():
            self.rec.spawn()
        path.parent.mkdir(parents=True, exist_ok=True)
        self.rec.save(path)
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def _at(self, t: float) -> None:
        self.rr.set_time("arm_time", duration=float(t), recording=self.rec)

    def frame(self, t: float, frame: Frame, mask: np.ndarray, tool_pose: np.ndarray) -> None:
        rr = self.rr
        self._at(t)
        self.rec.log("camera/color", rr.Image(frame.color))
        self.rec.log("camera/depth", rr.DepthImage(frame.depth_m, meter=1.0))
        self.rec.log("camera/mask", rr.SegmentationImage(mask.astype(np.uint8)))
        self.rec.log("world/gripper", rr.Transform3D(translation=tool_pose[:3, 3], mat3x3=tool_pose[:3, :3]))
        if frame.T_base_camera is not None:
            T = frame.T_base_camera
            self.rec.log("world/camera", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))

    def cloud(self, points: np.ndarray) -> None:
        self.rec.log("world/object", self.rr.Points3D(np.asarray(points, np.float32)), static=True)

    def axis(self, t: float, axis: Axis, opened: float) -> None:
        rr = self.rr
        self._at(t)
        d = AXIS_LENGTH_M * axis.direction / np.linalg.norm(axis.direction)
        self.rec.log("world/axis", rr.Arrows3D(origins=[axis.origin - d / 2], vectors=[d]))
        self.rec.log("opening", rr.Scalars(opened))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


def _has_display() -> bool:
    return sys.platform == "darwin" or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
