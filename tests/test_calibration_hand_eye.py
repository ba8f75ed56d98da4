"""Hand-eye solvers (OpenCV's and ours) on synthetic exact poses (both setups), refinement under pixel noise,
degenerate pose sets."""

import cv2
import numpy as np
import pytest

from calibration.board import BoardConfig
from calibration.detect import BoardView
from calibration.hand_eye import METHODS, SETUPS, Sample, calibrate, check_pose_set, solve
from calibration.intrinsics import calibrate_intrinsics
from calibration.solvers import HAND_EYE, ROBOT_WORLD, nearest_rotation, source
from calibration.transforms import from_rt, inv, pose_error, spread
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

INTRINSICS = Intrinsics.from_fov(640, 480, 65.0)
K = INTRINSICS.K
POINTS = np.asarray(BoardConfig().board().getChessboardCorners(), float)
# Ground truth (camera, board): eye-to-hand T_base_camera, T_tool_board; eye-in-hand T_tool_camera, T_base_board.
TRUTH = {
    "eye-to-hand": (from_rt([1.9, 0.1, 0.2], [0.4, -0.9, 0.7]), from_rt([np.pi, 0.05, 0.1], [0.09, -0.13, 0.03])),
    "eye-in-hand": (from_rt([0.05, -0.1, 0.02], [0.05, 0.0, -0.09]), from_rt([np.pi, 0.0, 0.3], [0.5, -0.2, 0.0])),
}


def tool_poses(setup: str, n: int, rng: np.random.Generator, axis: np.ndarray | None = None) -> list[np.ndarray]:
    """Tool poses from which the board stays in front of the camera; rotations about `axis` only if given."""
    T_camera, T_board = TRUTH[setup]
    poses = []
    for _ in range(n):
        rotvec = rng.normal(0.0, 0.25, 3) if axis is None else axis * rng.uniform(-0.4, 0.4)
        D = from_rt(rotvec, rng.normal(0.0, 0.04, 3))
        if setup == "eye-to-hand":  # board 0.6 m in front of the camera, perturbed
            C0 = from_rt([0.0, 0.0, 0.0], [-0.1, -0.13, 0.6])
            poses.append(T_camera @ C0 @ D @ inv(T_board))
        else:  # camera 0.5 m above the board, perturbed
            C0 = from_rt([0.0, 0.0, 0.0], [-0.1, -0.13, 0.5])
            poses.append(T_board @ inv(C0 @ D) @ inv(T_camera))
    return poses


def samples_for(setup: str, poses: list[np.ndarray], rng: np.random.Generator, pixel_sigma: float = 0.0) -> list:
    T_camera, T_board = TRUTH[setup]
    samples = []
    for T in poses:
        C = inv(T_camera) @ T @ T_board if setup == "eye-to-hand" else inv(T_camera) @ inv(T) @ T_board
        px, _ = cv2.projectPoints(POINTS, cv2.Rodrigues(C[:3, :3])[0], C[:3, 3], K, np.zeros(5))
        px = px.reshape(-1, 2) + rng.normal(0.0, pixel_sigma, (len(POINTS), 2))
        view = BoardView(px, np.arange(len(POINTS)), POINTS)
        if pixel_sigma > 0:  # the board pose as the routine gets it: PnP on the noisy corners
            _, rvec, tvec = cv2.solvePnP(POINTS, px, K, np.zeros(5), flags=cv2.SOLVEPNP_IPPE)
            C = from_rt(rvec, tvec)
        samples.append(Sample(T, C, view))
    return samples


@pytest.mark.parametrize("setup", SETUPS)
@pytest.mark.parametrize("method", [*HAND_EYE, *ROBOT_WORLD])
def test_each_solver_is_exact_on_exact_poses(setup, method):
    rng = np.random.default_rng(1)
    solution = solve(samples_for(setup, tool_poses(setup, 12, rng), rng), setup, method, K)
    mm, deg = pose_error(solution.T_camera, TRUTH[setup][0])
    assert mm < 0.01 and deg < 0.001
    mm, deg = pose_error(solution.T_board, TRUTH[setup][1])
    assert mm < 0.01 and deg < 0.001
    assert solution.reprojection_px < 1e-4 and solution.spread_mm < 0.01


def test_the_routine_runs_opencv_where_ours_is_not_measured_better():
    assert set(METHODS) <= set(HAND_EYE) | set(ROBOT_WORLD)
    assert {m for m in METHODS if source(m) == "opencv"} == {"tsai", "park", "horaud", "daniilidis", "shah"}
    assert {m for m in [*HAND_EYE, *ROBOT_WORLD] if source(m) == "opencv"} >= {"andreff-opencv", "li-opencv"}


@pytest.mark.parametrize("setup", SETUPS)
@pytest.mark.parametrize("method", [cv2.CALIB_HAND_EYE_TSAI, cv2.CALIB_HAND_EYE_PARK, cv2.CALIB_HAND_EYE_HORAUD,
                                    cv2.CALIB_HAND_EYE_ANDREFF, cv2.CALIB_HAND_EYE_DANIILIDIS])
def test_opencv_calibrate_hand_eye_recovers_the_exact_transform(setup, method):
    """cv2.calibrateHandEye itself, called as its documentation says: eye-in-hand with the gripper-to-base poses
    (T_base_tool), eye-to-hand with them inverted (T_tool_base); it returns the camera in the gripper, resp. base."""
    rng = np.random.default_rng(7)
    samples = samples_for(setup, tool_poses(setup, 10, rng), rng)
    gripper = [s.T_base_tool if setup == "eye-in-hand" else inv(s.T_base_tool) for s in samples]
    target = [s.T_camera_board for s in samples]
    R, t = cv2.calibrateHandEye([g[:3, :3] for g in gripper], [g[:3, 3:] for g in gripper],
                                [c[:3, :3] for c in target], [c[:3, 3:] for c in target], method=method)
    mm, deg = pose_error(from_rt(cv2.Rodrigues(R)[0], t.ravel()), TRUTH[setup][0])
    assert mm < 0.01 and deg < 0.001


@pytest.mark.parametrize("setup", SETUPS)
def test_refined_best_is_sub_millimetre_with_pixel_noise(setup):
    rng = np.random.default_rng(2)
    samples = samples_for(setup, tool_poses(setup, 15, rng), rng, pixel_sigma=0.3)
    best, solutions = calibrate(samples, setup, K)
    assert len(solutions) == len(METHODS) and best.refined
    assert best.reprojection_px <= min(s.reprojection_px for s in solutions)
    mm, deg = pose_error(best.T_camera, TRUTH[setup][0])
    assert mm < 1.0 and deg < 0.1
    assert best.method == min(solutions, key=lambda s: s.score).method


@pytest.mark.parametrize("setup", SETUPS)
def test_too_few_poses_are_rejected(setup):
    rng = np.random.default_rng(3)
    samples = samples_for(setup, tool_poses(setup, 2, rng), rng)
    with pytest.raises(CalibrationError, match="at least 3 poses"):
        calibrate(samples, setup, K)


@pytest.mark.parametrize("setup", SETUPS)
def test_parallel_rotation_axes_are_rejected(setup):
    rng = np.random.default_rng(4)
    axis = np.array([0.0, 0.6, 0.8])
    poses = tool_poses(setup, 10, rng, axis=axis)
    # eye-in-hand solvers see the tool's motions in the tool frame (R_i^T R_j), eye-to-hand in the base (R_i R_j^T)
    R0 = poses[0][:3, :3]
    turned = [R0 @ cv2.Rodrigues(axis * a)[0] if setup == "eye-in-hand" else cv2.Rodrigues(axis * a)[0] @ R0
              for a in np.linspace(-0.4, 0.4, len(poses))]
    poses = [from_rt(R, T[:3, 3]) for R, T in zip(turned, poses, strict=True)]
    with pytest.raises(CalibrationError, match="parallel axes"):
        check_pose_set(setup, poses)


def test_tiny_rotations_are_rejected():
    poses = [from_rt([0.0, 0.0, 0.01 * i], [0.4, 0.1 * i, 0.5]) for i in range(6)]
    with pytest.raises(CalibrationError, match="at most"):
        check_pose_set("eye-in-hand", poses)


def test_unknown_method_and_setup():
    rng = np.random.default_rng(5)
    samples = samples_for("eye-in-hand", tool_poses("eye-in-hand", 6, rng), rng)
    with pytest.raises(CalibrationError, match="unknown hand-eye method"):
        solve(samples, "eye-in-hand", "magic", K)
    with pytest.raises(CalibrationError, match="unknown hand-eye setup"):
        solve(samples, "eye-on-head", "tsai", K)


def test_intrinsics_from_views_recover_the_focal_length():
    rng = np.random.default_rng(6)
    views = [s.view for s in samples_for("eye-in-hand", tool_poses("eye-in-hand", 10, rng), rng, pixel_sigma=0.1)]
    result = calibrate_intrinsics(views, 640, 480)
    assert result.intrinsics.fx == pytest.approx(INTRINSICS.fx, rel=0.01)
    assert result.intrinsics.cy == pytest.approx(INTRINSICS.cy, abs=3.0)
    assert result.rms_px < 0.3 and result.views == 10
    with pytest.raises(CalibrationError, match="at least 4 board views"):
        calibrate_intrinsics(views[:2], 640, 480)


def test_spread_and_nearest_rotation():
    T = from_rt([0.1, 0.2, 0.3], [1.0, 2.0, 3.0])
    assert spread([T, T, T]) == pytest.approx((0.0, 0.0), abs=1e-4)
    moved = T.copy()
    moved[0, 3] += 0.002
    assert spread([T, moved])[0] == pytest.approx(1.0, abs=1e-6)  # each 1 mm from the mean
    R = T[:3, :3] + 1e-3
    assert np.allclose(nearest_rotation(R) @ nearest_rotation(R).T, np.eye(3))
