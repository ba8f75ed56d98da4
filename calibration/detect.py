"""ChArUco detection (OpenCV's `CharucoDetector`) and the board's pose in the camera frame by PnP."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calibration.board import BoardConfig
from drivers.camera.base import Intrinsics

MIN_CORNERS = 6  # fewer interpolated chessboard corners give no trustworthy pose


@dataclass(frozen=True)
class BoardView:
    """Chessboard corners seen in one image: pixels (N, 2), their ids (N,) and board-frame points (N, 3) m."""

    pixels: np.ndarray
    ids: np.ndarray
    points: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class BoardPose:
    """The board frame's pose in the camera frame and the RMS reprojection error (px) of its corners."""

    T_camera_board: np.ndarray
    rms_px: float
    view: BoardView


class BoardDetector:
    """Finds a `BoardConfig` board in RGB or grey images."""

    def __init__(self, cfg: BoardConfig, min_corners: int = MIN_CORNERS) -> None:
        self.cfg = cfg
        self.board = cfg.board()
        self.min_corners = max(int(min_corners), 4)
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        self._detector = cv2.aruco.CharucoDetector(self.board, cv2.aruco.CharucoParameters(), params)

    def detect(self, image: np.ndarray) -> BoardView | None:
        """The board's chessboard corners in `image` (H, W, 3 RGB or H, W grey); None with fewer than
        `min_corners` or when they are all on one line."""
        grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY) if image.ndim == 3 else image
        corners, ids, _, _ = self._detector.detectBoard(np.ascontiguousarray(grey))
        if ids is None or len(ids) < self.min_corners:
            return None
        if self.board.checkCharucoCornersCollinear(ids):
            return None
        ids = ids.reshape(-1).astype(int)
        points = np.asarray(self.board.getChessboardCorners(), float)[ids]
        return BoardView(corners.reshape(-1, 2).astype(float), ids, points)

    def pose(self, image: np.ndarray, intrinsics: Intrinsics, distortion: np.ndarray | None = None) -> BoardPose | None:
        """Detect the board and solve its pose (planar IPPE, then Levenberg-Marquardt); None if not seen."""
        view = self.detect(image)
        return None if view is None else solve_board_pose(view, intrinsics.K, distortion)


def solve_board_pose(view: BoardView, K: np.ndarray, distortion: np.ndarray | None = None) -> BoardPose:
    """PnP of one view: the pose of the board in the camera frame."""
    dist = np.zeros(5) if distortion is None else np.asarray(distortion, float)
    obj, img = view.points.astype(np.float64), view.pixels.astype(np.float64)
    _, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0]
    T[:3, 3] = tvec.ravel()
    return BoardPose(T, rms, view)
