"""Closed-form hand-eye solvers by name: OpenCV's `calibrateHandEye` (AX = XB) and `calibrateRobotWorldHandEye`
(AX = ZB), and our numpy versions (calibration.solvers_numpy) where those measure better.

Model (see calibration.hand_eye): board pose C_i = A @ M_i @ B, with M_i the known robot transform. An AX = XB
solver returns X = A^-1: OpenCV's "gripper poses" are G_i = M_i^-1 and its "target poses" C_i (for eye-to-hand
M_i = T_base_tool, so G_i are the inverted robot poses, as OpenCV's documentation says). An AX = ZB solver returns
(A, B): OpenCV's world-to-camera poses are C_i, its base-to-gripper poses M_i, and it returns A and B^-1.

`HAND_EYE` and `ROBOT_WORLD` hold every solver, OpenCV's under the method's name and ours as NAME-numpy, except
that `andreff` and `li` are ours and OpenCV's are andreff-opencv and li-opencv: OpenCV's solve rotation and
translation in one linear system, and their translation errs several times more under pixel noise (`deploy bench
calibration`). `METHODS` are the ones the routine runs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import cv2
import numpy as np

from calibration import solvers_numpy
from calibration.transforms import inv

Poses = Sequence[np.ndarray]
HandEyeSolver = Callable[[Poses, Poses], np.ndarray]
RobotWorldSolver = Callable[[Poses, Poses], tuple[np.ndarray, np.ndarray]]
nearest_rotation = solvers_numpy.nearest_rotation


def _rotations(poses: Poses) -> list[np.ndarray]:
    return [np.asarray(T, float)[:3, :3] for T in poses]


def _translations(poses: Poses) -> list[np.ndarray]:
    return [np.asarray(T, float)[:3, 3].reshape(3, 1) for T in poses]


def _pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def opencv_hand_eye(method: int) -> HandEyeSolver:
    """An AX = XB solver (X = A^-1) by `cv2.calibrateHandEye` with `method` (a cv2.CALIB_HAND_EYE_* flag)."""

    def solve(M: Poses, C: Poses) -> np.ndarray:
        G = [inv(m) for m in M]
        R, t = cv2.calibrateHandEye(_rotations(G), _translations(G), _rotations(C), _translations(C), method=method)
        return _pose(R, t)

    return solve


def opencv_robot_world(method: int) -> RobotWorldSolver:
    """An AX = ZB solver ((A, B)) by `cv2.calibrateRobotWorldHandEye` with `method` (CALIB_ROBOT_WORLD_HAND_EYE_*)."""

    def solve(M: Poses, C: Poses) -> tuple[np.ndarray, np.ndarray]:
        R_w, t_w, R_a, t_a = cv2.calibrateRobotWorldHandEye(_rotations(C), _translations(C), _rotations(M),
                                                            _translations(M), method=method)
        return _pose(R_a, t_a), inv(_pose(R_w, t_w))

    return solve


HAND_EYE: dict[str, HandEyeSolver] = {
    "tsai": opencv_hand_eye(cv2.CALIB_HAND_EYE_TSAI),
    "park": opencv_hand_eye(cv2.CALIB_HAND_EYE_PARK),
    "horaud": opencv_hand_eye(cv2.CALIB_HAND_EYE_HORAUD),
    "daniilidis": opencv_hand_eye(cv2.CALIB_HAND_EYE_DANIILIDIS),
    "andreff": solvers_numpy.andreff,
    "andreff-opencv": opencv_hand_eye(cv2.CALIB_HAND_EYE_ANDREFF),
    "tsai-numpy": solvers_numpy.tsai,
    "park-numpy": solvers_numpy.park,
    "horaud-numpy": solvers_numpy.horaud,
}
ROBOT_WORLD: dict[str, RobotWorldSolver] = {
    "shah": opencv_robot_world(cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH),
    "li": solvers_numpy.li,
    "li-opencv": opencv_robot_world(cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI),
    "shah-numpy": solvers_numpy.shah,
}
METHODS: tuple[str, ...] = ("tsai", "park", "horaud", "daniilidis", "andreff", "shah", "li")


def source(method: str) -> str:
    """Whose implementation `method` is: "opencv" or "numpy" (ours)."""
    ours = method.endswith("-numpy") or method in ("andreff", "li")
    return "numpy" if ours else "opencv"
