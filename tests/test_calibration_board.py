"""ChArUco boards: printable rendering at true scale, detection and PnP on synthetic camera images."""

import re

import cv2
import numpy as np
import pytest
from PIL import Image

from calibration.board import (
    INCH_M,
    PRINT_MARGIN_M,
    BoardConfig,
    fits_a4_and_letter,
    render_board,
    render_page,
    write_board,
)
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


def _media_box_mm(pdf) -> tuple[float, float]:
    box = [float(v) for v in re.search(rb"/MediaBox \[\s*([\d.]+) ([\d.]+) ([\d.]+) ([\d.]+)", pdf.read_bytes())
           .groups()]
    return box[2] / 72 * 25.4, box[3] / 72 * 25.4  # points: 1/72 inch


def test_default_page_fits_a4_and_letter_and_the_board_is_true_scale(tmp_path):
    cfg = BoardConfig()
    width, height = _media_box_mm(write_board(cfg, tmp_path / "board.pdf", dpi=300))
    assert width <= 210.0 and height <= 279.4  # A4 is 210 x 297 mm, Letter 215.9 x 279.4 mm
    assert fits_a4_and_letter(cfg)
    page = render_page(cfg, 300)
    assert page.shape == (round(height / 25.4 * 300), round(width / 25.4 * 300))
    dark = np.argwhere(page < 128)  # the board's outer squares are black: its extent is the squares area
    rows, cols = dark[:, 0], dark[:, 1]
    dark_rows = np.unique(rows)
    gap = np.argmax(np.diff(dark_rows))  # the white gap between the board and the parameters' line under it
    on_board = rows <= dark_rows[gap]
    printable = PRINT_MARGIN_M / INCH_M * 300
    assert cols.min() > printable and cols.max() < page.shape[1] - printable
    assert rows.min() > printable and rows.max() < page.shape[0] - printable
    board_rows, board_cols = rows[on_board], cols[on_board]
    assert (board_cols.max() - board_cols.min() + 1) / 300 * INCH_M == pytest.approx(cfg.size_m[0], abs=0.0003)
    assert (board_rows.max() - board_rows.min() + 1) / 300 * INCH_M == pytest.approx(cfg.size_m[1], abs=0.0003)
    png = write_board(cfg, tmp_path / "board.png", dpi=300)
    with Image.open(png) as im:
        assert im.info["dpi"] == pytest.approx((300, 300), abs=0.01) and im.size == (page.shape[1], page.shape[0])


def test_the_page_prints_the_parameters_under_the_board():
    cfg = BoardConfig((5, 7), 0.034, 0.025, "DICT_5X5_100")
    assert cfg.describe().startswith("ChArUco 5x7 squares of 34 mm, markers 25 mm, DICT_5X5_100")
    page = render_page(cfg, 200)
    text_band = page[int(page.shape[0] * 0.9):]
    assert (text_band < 128).sum() > 500  # the line is there
    plain = render_page(cfg, 200)[: int(page.shape[0] * 0.9)]
    assert (plain < 128).any()
    other = render_page(BoardConfig((5, 7), 0.034, 0.025, "DICT_4X4_50"), 200)[int(page.shape[0] * 0.9):]
    assert (other != text_band).any()  # another dictionary prints another line


def test_a_board_larger_than_the_sheet_gets_a_page_of_its_own(tmp_path):
    cfg = BoardConfig(square_m=0.040, marker_m=0.030)
    assert not fits_a4_and_letter(cfg)
    width, height = _media_box_mm(write_board(cfg, tmp_path / "board.pdf", dpi=150))
    assert width > cfg.size_m[0] * 1e3 + 18 and height > cfg.size_m[1] * 1e3 + 18 + 4  # margins, the line


def test_an_existing_board_file_is_kept_without_overwrite(tmp_path):
    path = tmp_path / "board.png"
    path.write_bytes(b"mine")
    with pytest.raises(CalibrationError, match="already exists: pass --overwrite"):
        write_board(BoardConfig(), path, dpi=100)
    assert path.read_bytes() == b"mine"
    write_board(BoardConfig(), path, dpi=100, overwrite=True)
    with Image.open(path) as im:
        assert im.format == "PNG"
    assert [p.name for p in tmp_path.iterdir()] == ["board.png"]


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
