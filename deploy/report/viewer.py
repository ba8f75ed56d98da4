"""`--view` and `export --format rrd`: frames, clouds and axes to rerun (rerun-sdk, extra `axisloop[viewer]`).

`RerunViewer` logs on the `time` timeline (seconds: arm time in an episode, camera time in a recording): the
camera (its pose in the base frame and a pinhole, so colour, depth and the object mask sit in 3D), the
gripper pose, the object cloud of the first frame, the axis acted on at each step, the true axis in
simulation and the opening. Every log goes at once to the .rrd file and, when a display is available, to a
live viewer spawned for it (rerun's multi-sink `set_sinks`): `rerun RUN/episode.rrd` replays it later.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from deploy.errors import ConfigError
from deploy.geometry.types import Axis
from drivers.camera.base import Frame, Intrinsics

AXIS_LENGTH_M = 0.6
ESTIMATED_RGB = (230, 120, 20)
TRUE_RGB = (40, 200, 60)


class RerunViewer:
    """A rerun recording saved at `path`; `spawn` (default: when a display is available) also streams it to a
    live viewer started here. The file and the viewer open with the first thing logged (a recording's folder
    exists by then)."""

    def __init__(self, path: Path, spawn: bool | None = None, name: str = "axisloop") -> None:
        try:
            import rerun as rr
        except ImportError as exc:
            raise ConfigError("--view needs the rerun viewer: pip install 'axisloop[viewer]' "
                              "(or run without --view)") from exc
        self.rr = rr
        self.path = Path(path)
        self.name = name
        self.spawn = spawn if spawn is not None else _has_display()
        self._rec = None
        self._intrinsics: Intrinsics | None = None

    @property
    def rec(self):
        """The recording stream, opened on first use: to the file and, with `spawn`, to a live viewer."""
        if self._rec is None:
            rr = self.rr
            self._rec = rr.RecordingStream(self.name)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            sinks = [rr.FileSink(str(self.path))]
            if self.spawn:
                self._rec.spawn(connect=False)  # start the viewer; the gRPC sink below streams to it
                sinks.append(rr.GrpcSink())
            self._rec.set_sinks(*sinks)
            self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        return self._rec

    def _at(self, t: float) -> None:
        self.rr.set_time("time", duration=float(t), recording=self.rec)

    def camera(self, intrinsics: Intrinsics, T_base_camera: np.ndarray | None) -> None:
        """The camera's pinhole (OpenCV axes: x right, y down, z forward) and, when known, its pose."""
        rr = self.rr
        if intrinsics != self._intrinsics:
            self._intrinsics = intrinsics
            self.rec.log("world/camera/image", rr.Pinhole(image_from_camera=intrinsics.K,
                                                          resolution=[intrinsics.width, intrinsics.height],
                                                          camera_xyz=rr.ViewCoordinates.RDF), static=True)
        if T_base_camera is not None:
            T = np.asarray(T_base_camera, float)
            self.rec.log("world/camera", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))

    def frame(self, t: float, frame: Frame, mask: np.ndarray | None = None,
              tool_pose: np.ndarray | None = None) -> None:
        """One frame at time `t` (s): colour, depth, the object mask and the gripper pose where given."""
        rr = self.rr
        self._at(t)
        self.camera(frame.intrinsics, frame.T_base_camera)
        self.rec.log("world/camera/image/color", rr.Image(frame.color))
        self.rec.log("world/camera/image/depth", rr.DepthImage(frame.depth_m, meter=1.0))
        if mask is not None:
            self.rec.log("world/camera/image/mask", rr.SegmentationImage(np.asarray(mask).astype(np.uint8)))
        if tool_pose is not None:
            self.rec.log("world/gripper", rr.Transform3D(translation=tool_pose[:3, 3], mat3x3=tool_pose[:3, :3]))
            self.rec.log("world/gripper/point", rr.Points3D([[0.0, 0.0, 0.0]], radii=0.01))

    def cloud(self, points: np.ndarray) -> None:
        """The object's cloud of the first frame (base frame, m)."""
        self.rec.log("world/object", self.rr.Points3D(np.asarray(points, np.float32)), static=True)

    def axis(self, t: float, axis: Axis, opened: float | None, source: str | None = None,
             step: int | None = None) -> None:
        """The axis acted on (or estimated) at time `t` and the opening then (m or deg; None: not known)."""
        self._at(t)
        label = f"step {step}" if step is not None else "estimate"
        label += f" ({source})" if source else ""
        self.rec.log("world/axis/estimated", self._arrow(axis, ESTIMATED_RGB, label))
        if opened is not None:
            self.rec.log("opening", self.rr.Scalars(opened))

    def true_axis(self, axis: Axis) -> None:
        """The simulation's true joint axis (for the eye only: the controller never sees it)."""
        self.rec.log("world/axis/true", self._arrow(axis, TRUE_RGB, "true axis"), static=True)

    def _arrow(self, axis: Axis, color: tuple[int, int, int], label: str):
        d = AXIS_LENGTH_M * np.asarray(axis.direction, float) / np.linalg.norm(axis.direction)
        return self.rr.Arrows3D(origins=[np.asarray(axis.origin, float) - d / 2], vectors=[d], colors=[color],
                                labels=[label])

    def close(self) -> None:
        """Write everything logged to the file (and the viewer) and end the recording."""
        if self._rec is not None:
            self._rec.flush()
            self._rec.disconnect()


def _has_display() -> bool:
    return sys.platform == "darwin" or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
