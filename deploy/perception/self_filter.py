"""The self-filter: the pixels where the camera sees the robot itself, so that they are never the object's.

Each link's collision mesh, posed by the measured joints, is projected with the camera's (calibrated) pose; the
convex hull of its vertices in the image is the link's silhouette. A pixel inside it sees the robot unless its
depth is clearly in front of the link (something between the camera and the arm). Silhouettes are grown by
`margin_m` at the link's distance, for the calibration's error and the depth noise.
"""

from __future__ import annotations

import cv2
import numpy as np

from deploy.geometry.cloud import project
from drivers.arm.body import RobotBody
from drivers.camera.base import Frame

MARGIN_M = 0.02  # silhouettes grow by this at the link's distance; depth in front by more than this is not robot
NEAR_M = 0.05  # links closer to the camera than this are not drawn
_OCTAGON = np.array([[np.cos(a), np.sin(a)] for a in np.arange(8) * np.pi / 4]) / np.cos(np.pi / 8)  # covers a disk


class SelfFilter:
    """`mask(frame, q, gripper_width_m)`: (H, W) bool, True where the robot is."""

    def __init__(self, body: RobotBody, margin_m: float = MARGIN_M) -> None:
        self.body, self.margin_m = body, margin_m

    def mask(self, frame: Frame, q: np.ndarray, gripper_width_m: float = 0.0, depth_test: bool = True) -> np.ndarray:
        """The robot's pixels; without `depth_test`, where the arm at `q` would hide the scene (planning)."""
        h, w = frame.depth_m.shape
        robot = np.zeros((h, w), bool)
        if frame.T_base_camera is None:
            return robot
        T = np.linalg.inv(frame.T_base_camera)
        K = frame.intrinsics
        depth = frame.depth_m
        for vertices in self.body.links(q, gripper_width_m):
            cam = vertices @ T[:3, :3].T + T[:3, 3]
            if cam[:, 2].min() < NEAR_M:
                continue
            uv = project(cam, K.K, K.dist_coeffs)
            grow = K.fx * self.margin_m / float(cam[:, 2].mean())
            hull = cv2.convexHull(uv.astype(np.float32))[:, 0]
            grown = (hull[:, None, :] + grow * _OCTAGON[None]).reshape(-1, 2)  # the hull grown by `grow` px
            x0, y0 = np.floor(grown.min(axis=0)).astype(int)
            x1, y1 = np.ceil(grown.max(axis=0)).astype(int) + 1
            if x1 <= 0 or y1 <= 0 or x0 >= w or y0 >= h:
                continue
            silhouette = np.zeros((y1 - y0, x1 - x0), np.uint8)  # the link's box
            cv2.fillConvexPoly(silhouette, cv2.convexHull(np.round(grown - [x0, y0]).astype(np.int32)), 1)
            cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
            inside = silhouette[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0].astype(bool)
            seen = depth[cy0:cy1, cx0:cx1]
            if depth_test:
                inside &= (seen == 0) | (seen > cam[:, 2].min() - self.margin_m)
            robot[cy0:cy1, cx0:cx1] |= inside
        return robot

    def apply(self, frame: Frame, q: np.ndarray, gripper_width_m: float = 0.0) -> tuple[Frame, np.ndarray]:
        """A copy of `frame` with the robot's depth set to 0 (no point), and the robot mask."""
        from dataclasses import replace

        robot = self.mask(frame, q, gripper_width_m)
        depth = frame.depth_m.copy()
        depth[robot] = 0.0
        return replace(frame, depth_m=depth), robot
