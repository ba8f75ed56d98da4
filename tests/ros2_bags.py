"""ROS 2 bags of realsense-ros topics for the tests, written with rosbags' own writer (rosbag2 .db3 or MCAP)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from realsense_recordings import Synthetic
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from drivers.camera.ros2_bag import EXTRINSICS_MSG, EXTRINSICS_TYPE

NS = "/camera/camera"


def _typestore():
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(EXTRINSICS_MSG, EXTRINSICS_TYPE))
    return store


def write_bag(path: Path, s: Synthetic, aligned: bool, storage: str = "sqlite3", color_encoding: str = "rgb8",
              depth_lag_ms: float = 3.0, extrinsics: bool = True, color_d: tuple = (0.0,) * 5) -> Path:
    """`s` as realsense-ros publishes it: colour, camera_info (its plumb_bob coefficients `color_d`), and either
    aligned depth or depth with its camera_info and (with `extrinsics`) the depth-to-colour extrinsics; depth stamped
    `depth_lag_ms` after its colour image."""
    ts = _typestore()
    T = ts.types
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]

    def header(t_s: float, frame: str):
        sec = int(t_s)
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(
            round((t_s - sec) * 1e9))), frame_id=frame)

    def info(t_s: float, fx: float, frame: str, d: tuple = (0.0,) * 5):
        c = (s.width - 1) / 2, (s.height - 1) / 2
        K = np.array([fx, 0, c[0], 0, fx, c[1], 0, 0, 1], float)
        return T["sensor_msgs/msg/CameraInfo"](
            header=header(t_s, frame), height=s.height, width=s.width, distortion_model="plumb_bob",
            d=np.array(d, float), k=K, r=np.eye(3).ravel(), p=np.zeros(12), binning_x=0, binning_y=0,
            roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))

    def image(t_s: float, pixels: np.ndarray, encoding: str, frame: str):
        data = np.ascontiguousarray(pixels)
        step = data.shape[1] * (data.shape[2] if data.ndim == 3 else 1) * data.dtype.itemsize
        return T["sensor_msgs/msg/Image"](header=header(t_s, frame), height=s.height, width=s.width,
                                          encoding=encoding, is_bigendian=0, step=step,
                                          data=np.frombuffer(data.tobytes(), np.uint8))

    depth_topic = f"{NS}/aligned_depth_to_color/image_raw" if aligned else f"{NS}/depth/image_rect_raw"
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns = {name: writer.add_connection(name, msgtype, typestore=ts) for name, msgtype in (
            (f"{NS}/color/image_raw", "sensor_msgs/msg/Image"),
            (f"{NS}/color/camera_info", "sensor_msgs/msg/CameraInfo"),
            (depth_topic, "sensor_msgs/msg/Image"),
            (f"{NS}/depth/camera_info", "sensor_msgs/msg/CameraInfo"),
            (f"{NS}/extrinsics/depth_to_color", EXTRINSICS_TYPE),
            ("/rosout", "rcl_interfaces/msg/Log"))}

        def put(topic: str, t_s: float, msg) -> None:
            writer.write(conns[topic], int(t_s * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))

        t0 = s.t0_ms / 1000
        if extrinsics:
            put(f"{NS}/extrinsics/depth_to_color", t0, T[EXTRINSICS_TYPE](
                rotation=np.eye(3).ravel(order="F"), translation=np.array([s.baseline_m, 0.0, 0.0])))
        for k, (depth, color) in enumerate(zip(s.depth, s.color, strict=True)):
            t = t0 + k * s.period_ms / 1000
            depth_mm = np.round(depth.astype(float) * s.depth_units_m * 1000).astype(np.uint16)
            rgb = color[..., ::-1] if color_encoding == "bgr8" else color
            put(f"{NS}/color/camera_info", t, info(t, s.color_fx, "camera_color_optical_frame", color_d))
            put(f"{NS}/color/image_raw", t, image(t, rgb, color_encoding, "camera_color_optical_frame"))
            if not aligned:
                put(f"{NS}/depth/camera_info", t, info(t, s.depth_fx, "camera_depth_optical_frame"))
            put(depth_topic, t + depth_lag_ms / 1000, image(t + depth_lag_ms / 1000, depth_mm, "16UC1",
                                                            "camera_depth_optical_frame"))
    return path
