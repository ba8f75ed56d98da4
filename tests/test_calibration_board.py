"""ChArUco boards: printable rendering at true scale, detection and PnP on synthetic camera images."""

import re

import cv2
import numpy as np
import pytest
from PIL import Image

from calibration.board import INCH_M, BoardConfig, render_board, write_board
from calibration.detect import BoardDetector
from calibration.transforms import from_rt, pose_error
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

INTRINSICS = Intrinsics.from_fov(640, 480, 65.0)


def camera_image(cfg: BoardConfig, T_camera_board: np.ndarray, px_per_m: float = 2500.0) -> np.ndarray:
    """The board seen by a pinhole camera at T_camera_board, on a grey background (exact homography warp)."""
    margin = 0.01
    texture = render_board(cfg, px_per_m, margin)
    tex_to_board = np.array([[1 / px_per_m, 0, 0.5 / px_per_m - margin], [0, 1 / px_per_m, 0.5 / px_per_m - margin],
                             [0, 0, 1]])
    board_to_image = INTRINSICS.K @ np.column_stack([T_camera_board[:3, 0], T_camera_board[:3, 1],
                                                     T_camera_board[:3, 3]])
    return cv2.warpPerspective(texture, board_to_image @ tex_to_board, (640, 480), flags=cv2.INTER_AREA,
                               borderValue=128)


def facing_camera(cfg: BoardConfig, distance_m: float, tilt_rad: np.ndarray) -> np.ndarray:
    """Board centre on the optical axis at distance_m, printed face toward the camera, tilted by tilt_rad."""
    T = from_rt(np.asarray(tilt_rad, float), [0.0, 0.0, distance_m])
    T[:3, 3] -= T[:3, :3] @ cfg.center_m
    return T


@pytest.mark.parametrize("tilt", [[0.0, 0.0, 0.0], [0.4, 0.0, 0.3], [-0.2, 0.5, -1.0]])
def test_detects_board_and_solves_its_pose(tilt):
    cfg = BoardConfig()
    T_true = facing_camera(cfg, 0.5, tilt)
    pose = BoardDetector(cfg).pose(camera_image(cfg, T_true), INTRINSICS)
    assert pose is not None
    assert len(pose.view) >= 20  # 4 x 6 inner corners on the default board
    mm, deg = pose_error(pose.T_camera_board, T_true)
    assert mm < 3.0 and deg < 0.5
    assert pose.rms_px < 0.5


def test_rgb_images_are_accepted_and_missing_board_gives_none():
    cfg = BoardConfig()
    grey = camera_image(cfg, facing_camera(cfg, 0.5, [0.1, 0.1, 0.0]))
    assert BoardDetector(cfg).detect(np.dstack([grey] * 3)) is not None
    assert BoardDetector(cfg).detect(np.full((480, 640), 128, np.uint8)) is None


def test_wrong_dictionary_does_not_detect():
    cfg = BoardConfig()
    image = camera_image(cfg, facing_camera(cfg, 0.5, [0.0, 0.2, 0.0]))
    assert BoardDetector(BoardConfig(dictionary="DICT_6X6_250")).detect(image) is None


def test_legacy_pattern_switch():
    """Boards with an even number of rows differ between the legacy (OpenCV < 4.6) and current patterns."""
    legacy, current = BoardConfig((5, 6), legacy=True), BoardConfig((5, 6), legacy=False)
    image = camera_image(legacy, facing_camera(legacy, 0.5, [0.2, 0.1, 0.0]))
    assert not np.array_equal(render_board(legacy, 1000), render_board(current, 1000))
    found = BoardDetector(legacy).detect(image)
    assert found is not None and len(found) >= 15
    wrong = BoardDetector(current).detect(image)
    assert wrong is None or len(wrong) < len(found) / 2


def test_png_and_pdf_are_true_scale(tmp_path):
    cfg = BoardConfig()
    png = write_board(cfg, tmp_path / "board.png", dpi=300, margin_m=0.01)
    with Image.open(png) as im:
        assert im.info["dpi"] == pytest.approx((300, 300), abs=0.01)
        width_m = im.size[0] / 300 * INCH_M
    assert width_m == pytest.approx(cfg.size_m[0] + 0.02, abs=0.0002)
    pdf = write_board(cfg, tmp_path / "board.pdf", dpi=300, margin_m=0.01)
    box = [float(v) for v in re.search(rb"/MediaBox \[\s*([\d.]+) ([\d.]+) ([\d.]+) ([\d.]+)", pdf.read_bytes())
           .groups()]
    assert box[2] / 72 * INCH_M == pytest.approx(cfg.size_m[0] + 0.02, abs=0.0003)  # points: 1/72 inch
    assert box[3] / 72 * INCH_M == pytest.approx(cfg.size_m[1] + 0.02, abs=0.0003)


@pytest.mark.parametrize("kwargs, message", [
    ({"marker_m": 0.05}, "smaller than the square"),
    ({"dictionary": "DICT_NOPE"}, "unknown ArUco dictionary"),
    ({"squares": (2, 2)}, "too small"),
    ({"squares": (12, 12), "dictionary": "DICT_4X4_50"}, "fewer than the 72 markers"),
])
def test_bad_board_configs_are_rejected(kwargs, message):
    with pytest.raises(CalibrationError, match=message):
        BoardConfig(**kwargs)


def test_bad_output_path(tmp_path):
    with pytest.raises(CalibrationError, match=r"\.png or \.pdf"):
        write_board(BoardConfig(), tmp_path / "board.svg")
    with pytest.raises(CalibrationError, match="does not exist"):
        write_board(BoardConfig(), tmp_path / "missing" / "board.png")
