"""ROS 2 bags of realsense-ros topics (rosbag2 .db3 or MCAP, a bag folder or its one file) as a camera, read
with the `rosbags` library.

Topics are found by name: colour `.../color/image_raw` (or `image_rect_raw`) with `.../color/camera_info`, and
depth either already aligned, `.../aligned_depth_to_color/image_raw`, or `.../depth/image_rect_raw` (or
`image_raw`) with `.../depth/camera_info` and the extrinsics `.../extrinsics/depth_to_color`
(realsense2_camera_msgs/Extrinsics: rotation column-major, translation in metres), re-projected onto the colour
image by `DepthAligner`. Images are sensor_msgs/Image: rgb8, bgr8, rgba8, bgra8 colour; 16UC1 / mono16 (mm)
or 32FC1 (m) depth. A colour and a depth image pair up when their header stamps are within half the colour
stream's frame period. The librealsense SDK's own .db3 recordings (topics under /device_0/) play through
`RealSenseReplayCamera` instead.
"""

from __future__ import annotations

from collections.abc import Iterator
from itertools import islice
from pathlib import Path

import cv2
import numpy as np

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.depth_align import DepthAligner
from drivers.errors import RecordingError

DEFAULT_PERIOD_S = 1 / 30  # a colour stream of one message: pair within half of this
EXTRINSICS_TYPE = "realsense2_camera_msgs/msg/Extrinsics"
EXTRINSICS_MSG = "float64[9] rotation\nfloat64[3] translation\n"
_TO_RGB = {"rgb8": None, "bgr8": cv2.COLOR_BGR2RGB, "rgba8": cv2.COLOR_RGBA2RGB, "bgra8": cv2.COLOR_BGRA2RGB}
_DEPTH = {"16UC1": (np.uint16, 0.001), "mono16": (np.uint16, 0.001), "32FC1": (np.float32, 1.0)}
_TOPICS = {  # role: topic name endings, in order of preference
    "color": ("/color/image_raw", "/color/image_rect_raw"),
    "color_info": ("/color/camera_info",),
    "aligned": ("/aligned_depth_to_color/image_raw",),
    "depth": ("/depth/image_rect_raw", "/depth/image_raw"),
    "depth_info": ("/depth/camera_info",),
    "extrinsics": ("/extrinsics/depth_to_color",),
}


def is_sdk_recording(path: Path) -> bool:
    """Whether the .db3 at `path` was written by the librealsense SDK (its topics live under /device_0/)."""
    reader = _open_reader(path)
    try:
        return any(c.topic == "/file_version" or c.topic.startswith("/device_") for c in reader.connections)
    finally:
        reader.close()


def _open_reader(path: Path):
    """An open rosbags Reader of `path`; RecordingError when it is not a readable bag."""
    from rosbags.rosbag2 import Reader

    try:
        reader = Reader(path)
        reader.open()
        return reader
    except Exception as exc:  # noqa: BLE001 - rosbags raises several types for unreadable bags
        raise RecordingError(f"cannot read ROS 2 bag {path}: {exc}; give a rosbag2 folder, .db3 or .mcap file "
                             "recorded with realsense-ros") from None


class Ros2BagCamera(Camera):
    """Plays a realsense-ros bag once, every colour/depth pair in order; RecordingError at the end."""

    depth_scale = 0.001  # metres per unit of the depth topic (16UC1 mm; 32FC1 m): connect() reads the encoding

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise RecordingError(f"ROS 2 bag {self.path} not found; check the path")
        self._messages: Iterator[tuple[str, object]] | None = None
        self._reader = None
        self._intrinsics: Intrinsics | None = None
        self._aligner: DepthAligner | None = None
        self._t0: float | None = None
        self.frames_read = 0

    @property
    def intrinsics(self) -> Intrinsics:
        self.connect()
        return self._intrinsics

    def connect(self) -> None:
        if self._reader is not None:
            return
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self._typestore = get_typestore(Stores.LATEST)
        self._typestore.register(get_types_from_msg(EXTRINSICS_MSG, EXTRINSICS_TYPE))
        self._reader = _open_reader(self.path)
        try:
            self._topics = _find_topics(self._reader.connections, self.path)
            self._setup()
        except Exception:
            self.disconnect()
            raise
        self._messages = self._read(self._topics["color"], self._depth_topic)
        self._t0, self.frames_read = None, 0

    def disconnect(self) -> None:
        if self._reader is not None:
            self._reader.close()
            self._reader, self._messages = None, None

    def _first(self, role: str):
        """The first message of `role`'s topic; None without one."""
        if role not in self._topics:
            return None
        return next((msg for _, msg in self._read(self._topics[role])), None)

    def _read(self, *topics: str) -> Iterator[tuple[str, object]]:
        connections = [c for c in self._reader.connections if c.topic in topics]
        for connection, _, raw in self._reader.messages(connections=connections):
            yield connection.topic, self._typestore.deserialize_cdr(raw, connection.msgtype)

    def _setup(self) -> None:
        """Intrinsics from the colour camera_info; the depth aligner unless depth is already aligned."""
        topics = self._topics
        color_info = self._first("color_info")
        if color_info is None:
            raise RecordingError(f"ROS 2 bag {self.path}: {topics['color_info']} holds no message: record the "
                                 "colour camera_info with the images")
        self._intrinsics = _intrinsics(color_info)
        stamps = [_stamp(msg) for _, msg in islice(self._read(topics["color"]), 2)]
        self._pair_tolerance_s = 0.5 * (stamps[1] - stamps[0] if len(stamps) == 2 and stamps[1] > stamps[0]
                                        else DEFAULT_PERIOD_S)
        if "aligned" in topics:
            self._depth_topic = topics["aligned"]
        else:
            self._aligner = self._depth_aligner()
            self._depth_topic = topics["depth"]
        depth = self._first("aligned" if "aligned" in topics else "depth")
        if depth is not None:
            self.depth_scale = _depth_encoding(depth)[1]

    def _depth_aligner(self) -> DepthAligner:
        """The aligner re-projecting the depth topic onto the colour image, from its camera_info and extrinsics."""
        topics = self._topics
        first = {role: self._first(role) for role in ("depth_info", "extrinsics")}
        missing = [role for role in ("depth", "depth_info", "extrinsics") if role not in topics or
                   first.get(role, True) is None]
        if missing:
            raise RecordingError(f"ROS 2 bag {self.path} has no aligned depth topic (.../aligned_depth_to_color/"
                                 f"image_raw) and lacks {', '.join(missing)}: record with align_depth.enable:=true "
                                 "or record the depth camera_info and extrinsics topics too")
        extrinsics = first["extrinsics"]
        R = np.reshape(np.asarray(extrinsics.rotation, float), (3, 3)).T  # column-major
        return DepthAligner(_intrinsics(first["depth_info"]), self._intrinsics, R,
                            np.asarray(extrinsics.translation, float))

    def read(self, timeout_s: float = 2.0) -> Frame:
        """The next colour/depth pair; RecordingError at the end of the bag."""
        self.connect()
        color = depth = None
        for topic, msg in self._messages:
            if topic == self._topics["color"]:
                color = msg
            else:
                depth = msg
            if color is None or depth is None:
                continue
            t_color, t_depth = _stamp(color), _stamp(depth)
            if abs(t_color - t_depth) <= self._pair_tolerance_s:
                return self._frame(color, depth, t_color)
            color, depth = (None, depth) if t_color < t_depth else (color, None)  # drop the older one
        raise RecordingError(f"end of ROS 2 bag {self.path} after {self.frames_read} frames")

    def _frame(self, color, depth, t: float) -> Frame:
        rgb = _color_image(color)
        depth_m = _depth_image(depth)
        if self._aligner is not None:
            depth_m = self._aligner.align(depth_m)
        if rgb.shape[:2] != (self._intrinsics.height, self._intrinsics.width) or depth_m.shape != rgb.shape[:2]:
            raise RecordingError(f"ROS 2 bag {self.path}: colour {rgb.shape[1]}x{rgb.shape[0]} and depth "
                                 f"{depth_m.shape[1]}x{depth_m.shape[0]} images do not match the colour camera_info "
                                 f"({self._intrinsics.width}x{self._intrinsics.height}); record them together")
        self._t0 = t if self._t0 is None else self._t0
        frame = Frame(index=self.frames_read, t=t - self._t0, color=rgb, depth_m=depth_m, intrinsics=self._intrinsics)
        self.frames_read += 1
        return frame


def _find_topics(connections, path: Path) -> dict[str, str]:
    """Role -> topic name, for the roles whose topic is in the bag."""
    names = [c.topic for c in connections]
    found = {}
    for role, endings in _TOPICS.items():
        for ending in endings:
            match = next((name for name in names if name.endswith(ending)), None)
            if match is not None:
                found[role] = match
                break
    if "color" not in found or "color_info" not in found:
        raise RecordingError(f"ROS 2 bag {path} has no realsense-ros colour topics (.../color/image_raw and "
                             f".../color/camera_info); it holds {', '.join(sorted(names)) or 'no topics'}")
    return found


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _intrinsics(info) -> Intrinsics:
    """A CameraInfo's intrinsics, with its lens when it is plumb_bob (OpenCV's k1 k2 p1 p2 k3: what realsense-ros
    writes for the RealSense lens models); another model is left out (pinhole)."""
    K = np.asarray(info.k, float).reshape(3, 3)
    coeffs = tuple(float(c) for c in info.d)
    lens = ("brown_conrady", coeffs) if info.distortion_model == "plumb_bob" and len(coeffs) == 5 else ()
    return Intrinsics(int(info.width), int(info.height), K[0, 0], K[1, 1], K[0, 2], K[1, 2], *lens)


def _pixels(msg, dtype: type, channels: int) -> np.ndarray:
    """The image's pixels as (height, width[, channels]) of `dtype`, honouring `step` and byte order."""
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    rows = np.frombuffer(np.asarray(msg.data, np.uint8).tobytes(), np.uint8).reshape(msg.height, msg.step)
    row_bytes = msg.width * channels * dt.itemsize
    image = np.ascontiguousarray(rows[:, :row_bytes]).view(dt).astype(dt.newbyteorder("="))
    return image.reshape(msg.height, msg.width, channels) if channels > 1 else image.reshape(msg.height, msg.width)


def _color_image(msg) -> np.ndarray:
    if msg.encoding not in _TO_RGB:
        raise RecordingError(f"colour encoding {msg.encoding!r} is not supported: record rgb8, bgr8, rgba8 or bgra8")
    image = _pixels(msg, np.uint8, 4 if msg.encoding.endswith("a8") else 3)
    conversion = _TO_RGB[msg.encoding]
    return image.copy() if conversion is None else cv2.cvtColor(image, conversion)


def _depth_encoding(msg) -> tuple[type, float]:
    """The pixel type and metres per unit of a depth image's encoding."""
    if msg.encoding not in _DEPTH:
        raise RecordingError(f"depth encoding {msg.encoding!r} is not supported: record 16UC1 (mm) or 32FC1 (m)")
    return _DEPTH[msg.encoding]


def _depth_image(msg) -> np.ndarray:
    dtype, scale = _depth_encoding(msg)
    depth = _pixels(msg, dtype, 1).astype(np.float32) * np.float32(scale)
    depth[~np.isfinite(depth)] = 0.0
    return depth
