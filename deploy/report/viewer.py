"""`--view` and `export --format rrd`: what the robot saw and did, to rerun (rerun-sdk, extra `axisloop[viewer]`).

`RerunViewer` logs on the `time` timeline (seconds: arm time in an episode, camera time in a recording):
- the camera: its pose in the base frame and pinholes, so that colour (JPEG), depth (16-bit PNG, mm, every 2nd
  pixel: shown as depth, in 3D) and the object mask's outline sit in 3D;
- the robot from its URDF (deploy/report/viewer_robot.py) posed by the measured joints, and every joint's measured
  and commanded value as scalars (`joints/NAME/measured`, `joints/NAME/commanded`), with the gripper's opening;
- the gripper's pose; the grasp; each motion's planned (commanded) and executed (measured) tool path;
- per step the object's cloud, its moving part and the handle; the axis acted on with its confidence (`axis/
  confidence`), the opening, and in simulation the true axis.
Every log goes at once to the .rrd file and, when a display is available, to a live viewer spawned for it (rerun's
multi-sink `set_sinks`): `rerun RUN/episode.rrd` replays it later.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from deploy.errors import ConfigError
from deploy.geometry.types import Axis
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import depth_units

AXIS_LENGTH_M = 0.6
ESTIMATED_RGB = (230, 120, 20)
TRUE_RGB = (40, 200, 60)
PLANNED_RGB, EXECUTED_RGB = (90, 140, 255), (255, 80, 80)
CLOUD_RGB, MOVING_RGB, HANDLE_RGB = (170, 170, 170), (255, 170, 0), (220, 40, 220)
JPEG_QUALITY = 80  # colour images: a thirtieth of the raw size, the furniture's edges still sharp
DEPTH_MM = 0.001  # depth images are logged as 16-bit millimetres (the viewer's default unit for integer depth)
DEPTH_DECIMATION = 2  # every 2nd depth pixel each way (as the RealSense decimation filter): a quarter of the bytes,
# the 3D view as dense as a look needs (the recording keeps every pixel)
CLOUD_POINTS = 5000  # a step's clouds are thinned to at most this many points each
MASK_RGB = (0, 220, 255)
BATCH_S, BATCH_BYTES = 1.0, 4 << 20  # logs are sent in chunks of up to a second or 4 MB: fewer, larger chunks (each
# carries its own schema) make a smaller file; a live viewer lags by at most the second


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
        self._robot = None
        self._joint_names: list[str] = []

    @property
    def live(self) -> bool:
        """Whether a live viewer is shown (else the recording goes to the file only)."""
        return self.spawn

    @property
    def rec(self):
        """The recording stream, opened on first use: to the file and, with `spawn`, to a live viewer."""
        if self._rec is None:
            rr = self.rr
            self._rec = rr.RecordingStream(self.name, batcher_config=rr.ChunkBatcherConfig(
                flush_tick=BATCH_S, flush_num_bytes=BATCH_BYTES))
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

    def robot(self, urdf: Path, arm_joints: Sequence[str], finger_joints: Sequence[str] = ()) -> None:
        """The robot's model from its URDF (static), posed from now on by `arm`."""
        from deploy.report.viewer_robot import RobotModel

        self._robot = RobotModel(self.rr, urdf, arm_joints, finger_joints)
        self._robot.log(self.rec)
        self._joint_names = list(arm_joints)

    def arm(self, t: float, q: np.ndarray, q_commanded: np.ndarray | None = None,
            gripper_width_m: float | None = None) -> None:
        """The arm at time `t`: the robot posed by the measured joints `q`, and `q`, the commanded joints and the
        gripper's opening (m) as scalars."""
        self._at(t)
        names = self._joint_names or [f"joint{i + 1}" for i in range(len(np.ravel(q)))]
        if self._robot is not None:
            self._robot.pose(self.rec, q, gripper_width_m)
        for kind, values in (("measured", q), ("commanded", q_commanded)):
            if values is not None:
                for name, value in zip(names, np.ravel(values), strict=False):
                    self.rec.log(f"joints/{name}/{kind}", self.rr.Scalars(float(value)))
        if gripper_width_m is not None:
            self.rec.log("joints/gripper_width_m", self.rr.Scalars(float(gripper_width_m)))

    def camera(self, intrinsics: Intrinsics, T_base_camera: np.ndarray | None) -> None:
        """The camera's pinhole (OpenCV axes: x right, y down, z forward) and, when known, its pose."""
        rr = self.rr
        if intrinsics != self._intrinsics:
            self._intrinsics = intrinsics
            n = DEPTH_DECIMATION
            for entity, K, size in (("image", intrinsics.K, (intrinsics.width, intrinsics.height)),
                                    ("depth", np.diag([1 / n, 1 / n, 1]) @ intrinsics.K,
                                     (len(range(0, intrinsics.width, n)), len(range(0, intrinsics.height, n))))):
                self.rec.log(f"world/camera/{entity}", rr.Pinhole(image_from_camera=K, resolution=list(size),
                                                                  camera_xyz=rr.ViewCoordinates.RDF), static=True)
        if T_base_camera is not None:
            self.rec.log("world/camera", _pose(rr, T_base_camera))

    def frame(self, t: float, frame: Frame, mask: np.ndarray | None = None,
              tool_pose: np.ndarray | None = None) -> None:
        """One frame at time `t` (s): colour (JPEG), depth (PNG, mm, decimated), the object mask's outline and the
        gripper pose where given."""
        rr = self.rr
        self._at(t)
        self.camera(frame.intrinsics, frame.T_base_camera)
        self.rec.log("world/camera/image/color", rr.Image(frame.color).compress(jpeg_quality=JPEG_QUALITY))
        depth = frame.depth_m[::DEPTH_DECIMATION, ::DEPTH_DECIMATION]
        self.rec.log("world/camera/depth/image", rr.EncodedDepthImage(_png(depth_units(depth, DEPTH_MM)[0]),
                                                                      media_type="image/png"))
        if mask is not None:
            self.rec.log("world/camera/image/mask", rr.LineStrips2D(_outline(mask), colors=[MASK_RGB], radii=1.0))
        if tool_pose is not None:
            self.rec.log("world/gripper", _pose(rr, tool_pose))
            self.rec.log("world/gripper/point", rr.Points3D([[0.0, 0.0, 0.0]], radii=0.01))

    def cloud(self, points: np.ndarray) -> None:
        """The object's cloud of the first frame (base frame, m)."""
        self.rec.log("world/object/first", self.rr.Points3D(_thin(points), colors=[CLOUD_RGB]), static=True)

    def step_clouds(self, t: float, cloud: np.ndarray, moving: np.ndarray | None,
                    handle: np.ndarray | None) -> None:
        """A step's clouds at time `t` (base frame, m): the object's, its moving part and the handle's."""
        rr = self.rr
        self._at(t)
        self.rec.log("world/object/cloud", rr.Points3D(_thin(cloud), colors=[CLOUD_RGB], radii=0.002))
        for name, points, color in (("moving_part", moving, MOVING_RGB), ("handle", handle, HANDLE_RGB)):
            if points is not None:
                self.rec.log(f"world/object/{name}", rr.Points3D(_thin(points), colors=[color], radii=0.004))

    def grasp(self, t: float, T_grasp: np.ndarray) -> None:
        """The planned grasp pose at time `t` (its axes; z: the approach direction)."""
        self._at(t)
        self.rec.log("world/grasp", _pose(self.rr, T_grasp), self.rr.TransformAxes3D(0.08))

    def motion(self, t: float, index: int, label: str, planned: np.ndarray, executed: np.ndarray) -> None:
        """Motion `index` (`label`), ended at time `t`: its planned (commanded) and executed (measured) tool paths,
        (N, 4, 4) poses each."""
        rr = self.rr
        self._at(t)
        for kind, poses, color in (("planned", planned, PLANNED_RGB), ("executed", executed, EXECUTED_RGB)):
            strip = np.asarray(poses, float)[:, :3, 3]
            self.rec.log(f"world/paths/{index:02d}/{kind}",
                         rr.LineStrips3D([strip], colors=[color], radii=0.002, labels=[f"{label} ({kind})"]))

    def axis(self, t: float, axis: Axis, opened: float | None, source: str | None = None,
             step: int | None = None) -> None:
        """The axis acted on (or estimated) at time `t`, its confidence, and the opening then (m or deg; None: not
        known)."""
        self._at(t)
        label = f"step {step}" if step is not None else "estimate"
        label += f" ({source})" if source else ""
        label += f", confidence {axis.confidence:.2f}"
        self.rec.log("world/axis/estimated", self._arrow(axis, ESTIMATED_RGB, label))
        self.rec.log("axis/confidence", self.rr.Scalars(float(axis.confidence)))
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


def _pose(rr, T: np.ndarray):
    T = np.asarray(T, float)
    return rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3])


def _png(image: np.ndarray) -> bytes:
    ok, encoded = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise ValueError(f"could not encode a {image.dtype} image of shape {image.shape} as PNG")
    return encoded.tobytes()


def _outline(mask: np.ndarray) -> list[np.ndarray]:
    """The mask's outer outlines as pixel polylines (closed)."""
    contours, _ = cv2.findContours(np.asarray(mask, bool).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return [np.vstack([c[:, 0, :], c[:1, 0, :]]).astype(np.float32) for c in contours]


def _thin(points: np.ndarray) -> np.ndarray:
    """At most CLOUD_POINTS of `points`, evenly spread through the array (float32)."""
    points = np.asarray(points, np.float32).reshape(-1, 3)
    step = max(1, int(np.ceil(len(points) / CLOUD_POINTS)))
    return points[::step]


def _has_display() -> bool:
    return sys.platform == "darwin" or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
