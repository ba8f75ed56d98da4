"""Hand-eye calibration: several closed-form solvers (calibration.solvers: OpenCV's, ours where they measure
better), the most consistent one refined.

Both setups share one model. Sample i pairs the tool pose T_base_tool_i (forward kinematics) with the
board pose C_i = T_camera_board_i (PnP), and C_i = A @ M_i @ B with two fixed unknowns:

    eye-in-hand (camera on the wrist, board fixed):  A = T_camera_tool, M_i = T_tool_base_i, B = T_base_board
    eye-to-hand (camera fixed, board on the tool):   A = T_camera_base, M_i = T_base_tool_i, B = T_tool_board

AX = XB solvers (OpenCV's `calibrateHandEye` methods; with G_i = M_i^-1 as the "gripper poses", which for
eye-to-hand is the usual trick of passing inverted robot poses) give A^-1; AX = ZB solvers
(`calibrateRobotWorldHandEye`'s) give A and B together. Consistency is the
spread, over samples, of the frame that is fixed in the base (eye-in-hand: the board, M_i^-1 A^-1 C_i;
eye-to-hand: the camera, M_i B C_i^-1). Refinement minimises the corners' reprojection error over A and B.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from scipy.optimize import least_squares

from calibration.detect import BoardView
from calibration.solvers import HAND_EYE, METHODS, ROBOT_WORLD
from calibration.transforms import from_rt, inv, mean_pose, rotation_angle_deg, spread
from drivers.errors import CalibrationError

Setup = Literal["eye-to-hand", "eye-in-hand"]
SETUPS: tuple[Setup, ...] = ("eye-to-hand", "eye-in-hand")
MIN_POSES = 3
MIN_ROTATION_DEG = 5.0  # the largest relative rotation between two poses must reach this
MIN_AXIS_SPREAD = 0.02  # second eigenvalue of the rotation axes' scatter matrix: 0 when all are parallel
DEG_PER_MM = 0.1  # consistency score = spread_mm + spread_deg / DEG_PER_MM


@dataclass(frozen=True)
class Sample:
    """One station of the routine: the tool pose (FK), the board pose in the camera and its corners."""

    T_base_tool: np.ndarray
    T_camera_board: np.ndarray
    view: BoardView


@dataclass(frozen=True)
class HandEyeSolution:
    """A solved calibration. `T_camera_side` = A and `T_target_side` = B of the module docstring.

    Residuals: RMS corner reprojection (px) and the spread of the base-fixed frame (mm, deg) over samples.
    """

    setup: Setup
    method: str
    T_camera_side: np.ndarray
    T_target_side: np.ndarray
    reprojection_px: float
    spread_mm: float
    spread_deg: float
    samples: int
    refined: bool = False

    @property
    def T_camera(self) -> np.ndarray:
        """Eye-to-hand: T_base_camera (the camera in the base). Eye-in-hand: T_tool_camera (on the tool)."""
        return inv(self.T_camera_side)

    @property
    def T_board(self) -> np.ndarray:
        """Eye-to-hand: T_tool_board (board on the tool). Eye-in-hand: T_base_board (board in the base)."""
        return self.T_target_side.copy()

    @property
    def score(self) -> float:
        return self.spread_mm + self.spread_deg / DEG_PER_MM


def robot_motions(setup: Setup, T_base_tool: Sequence[np.ndarray]) -> list[np.ndarray]:
    """M_i of the model for each tool pose."""
    if setup not in SETUPS:
        raise CalibrationError(f"unknown hand-eye setup {setup!r}: use eye-to-hand or eye-in-hand")
    return [np.asarray(T, float) if setup == "eye-to-hand" else inv(T) for T in T_base_tool]


def check_pose_set(setup: Setup, T_base_tool: Sequence[np.ndarray]) -> None:
    """Raise CalibrationError when the tool poses cannot determine a hand-eye transform: fewer than
    MIN_POSES, rotations too small, or all relative rotations about parallel axes."""
    n = len(T_base_tool)
    if n < MIN_POSES:
        raise CalibrationError(
            f"hand-eye calibration needs at least {MIN_POSES} poses with the board detected, got {n}: use 15 or "
            "more (--poses) and keep the board in view"
        )
    M = robot_motions(setup, T_base_tool)
    axes, largest = [], 0.0
    for i in range(n):
        for j in range(i + 1, n):
            R = M[i][:3, :3] @ M[j][:3, :3].T
            angle = rotation_angle_deg(R)
            largest = max(largest, angle)
            if angle >= 1.0:
                axes.append(cv2.Rodrigues(R)[0].ravel() / np.radians(angle))
    if largest < MIN_ROTATION_DEG:
        raise CalibrationError(
            f"the {n} poses turn the tool by at most {largest:.1f} deg: hand-eye needs rotations of "
            f"{MIN_ROTATION_DEG:.0f} deg or more (15-30 deg is best) about non-parallel axes"
        )
    a = np.asarray(axes)
    second = np.linalg.eigvalsh(a.T @ a / len(a))[1]
    if second < MIN_AXIS_SPREAD:
        raise CalibrationError(
            f"all {n} poses rotate the tool about parallel axes (axis spread {second:.3f} < {MIN_AXIS_SPREAD}): "
            "hand-eye is then undetermined along that axis; add poses tilted about other axes"
        )


def solve(samples: Sequence[Sample], setup: Setup, method: str, K: np.ndarray,
          distortion: np.ndarray | None = None) -> HandEyeSolution:
    """One solver (a name in calibration.solvers' HAND_EYE or ROBOT_WORLD) on the samples."""
    check_pose_set(setup, [s.T_base_tool for s in samples])
    M = robot_motions(setup, [s.T_base_tool for s in samples])
    C = [s.T_camera_board for s in samples]
    if method in HAND_EYE:
        A = inv(HAND_EYE[method](M, C))
        B = mean_pose([inv(m) @ inv(A) @ c for m, c in zip(M, C, strict=True)])
    elif method in ROBOT_WORLD:
        A, B = ROBOT_WORLD[method](M, C)
    else:
        raise CalibrationError(f"unknown hand-eye method {method!r}: use one of "
                               f"{', '.join((*HAND_EYE, *ROBOT_WORLD))}")
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise CalibrationError(f"hand-eye method {method} failed (non-finite result): add more varied poses")
    return evaluate(samples, setup, method, A, B, K, distortion)


def evaluate(samples: Sequence[Sample], setup: Setup, method: str, A: np.ndarray, B: np.ndarray, K: np.ndarray,
             distortion: np.ndarray | None = None, refined: bool = False) -> HandEyeSolution:
    """Residuals of a candidate (A, B) on the samples."""
    M = robot_motions(setup, [s.T_base_tool for s in samples])
    C = [s.T_camera_board for s in samples]
    if setup == "eye-in-hand":
        fixed = [inv(m) @ inv(A) @ c for m, c in zip(M, C, strict=True)]
    else:
        fixed = [m @ B @ inv(c) for m, c in zip(M, C, strict=True)]
    mm, deg = spread(fixed)
    errors = _reprojection(A, B, M, samples, K, distortion)
    rms = float(np.sqrt(np.mean(errors**2) * 2))
    return HandEyeSolution(setup, method, A, B, rms, mm, deg, len(samples), refined)


def refine(solution: HandEyeSolution, samples: Sequence[Sample], K: np.ndarray,
           distortion: np.ndarray | None = None) -> HandEyeSolution:
    """Minimise the corners' reprojection error over A and B (robust Huber loss, 1 px), from `solution`."""
    M = robot_motions(solution.setup, [s.T_base_tool for s in samples])

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return from_rt(x[:3], x[3:6]), from_rt(x[6:9], x[9:])

    A0, B0 = solution.T_camera_side, solution.T_target_side
    x0 = np.concatenate([cv2.Rodrigues(A0[:3, :3])[0].ravel(), A0[:3, 3], cv2.Rodrigues(B0[:3, :3])[0].ravel(),
                         B0[:3, 3]])
    fit = least_squares(lambda x: _reprojection(*unpack(x), M, samples, K, distortion), x0, loss="huber",
                        f_scale=1.0, x_scale="jac")
    A, B = unpack(fit.x)
    refined = evaluate(samples, solution.setup, solution.method, A, B, K, distortion, refined=True)
    return refined if refined.reprojection_px <= solution.reprojection_px else solution


def calibrate(samples: Sequence[Sample], setup: Setup, K: np.ndarray, distortion: np.ndarray | None = None,
              methods: Sequence[str] = METHODS, refine_best: bool = True) -> tuple[HandEyeSolution,
                                                                                   list[HandEyeSolution]]:
    """Every method in `methods`, the most consistent (lowest `score`) refined: (best, all unrefined)."""
    check_pose_set(setup, [s.T_base_tool for s in samples])
    solutions = []
    for method in methods:
        try:
            solutions.append(solve(samples, setup, method, K, distortion))
        except (np.linalg.LinAlgError, CalibrationError):
            continue
    if not solutions:
        raise CalibrationError(f"no hand-eye method converged on {len(samples)} samples: add more varied poses")
    best = min(solutions, key=lambda s: s.score)
    if refine_best:
        best = refine(best, samples, K, distortion)
    return best, solutions


def _reprojection(A: np.ndarray, B: np.ndarray, M: Sequence[np.ndarray], samples: Sequence[Sample], K: np.ndarray,
                  distortion: np.ndarray | None) -> np.ndarray:
    dist = np.zeros(5) if distortion is None else np.asarray(distortion, float)
    out = []
    for m, s in zip(M, samples, strict=True):
        T = A @ m @ B
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        projected, _ = cv2.projectPoints(s.view.points.astype(float), rvec, T[:3, 3], K, dist)
        out.append((projected.reshape(-1, 2) - s.view.pixels).ravel())
    return np.concatenate(out)

