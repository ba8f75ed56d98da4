"""ChArUco board configuration and a printable page at true scale (PNG with its dpi, or PDF): the board centred
on a sheet that both A4 and Letter hold, its parameters printed under it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from drivers.errors import CalibrationError

INCH_M = 0.0254
MAX_PAGE_M = (0.841, 1.189)  # A0, the largest ISO sheet: a board beyond it cannot be printed in one piece
MAX_SIDE_PX = 20000  # the rendered image's longest side (memory, and the PDF encoder's 65500 px)
SHEET_M = (0.210, 0.279)  # portrait sheet inside both A4 (210 x 297 mm) and Letter (215.9 x 279.4 mm)
PRINT_MARGIN_M = 0.00635  # what printers leave blank at each edge (a quarter inch, the usual Letter margin)
QUIET_M = 0.003  # white border kept around the board, the parameters' line beyond it
TEXT_M = 0.004  # height of the parameters' line


@dataclass(frozen=True)
class BoardConfig:
    """A ChArUco board: `squares` (columns, rows), square and marker sides in metres, an OpenCV ArUco
    dictionary name, and `legacy` for boards printed by OpenCV < 4.6 (chessboard pattern starting with a
    marker on even rows; `CharucoBoard.setLegacyPattern`). The default's page fits A4 and Letter (`page_m`)."""

    squares: tuple[int, int] = (5, 7)
    square_m: float = 0.036
    marker_m: float = 0.027
    dictionary: str = "DICT_4X4_50"
    legacy: bool = False

    def __post_init__(self) -> None:
        cols, rows = self.squares
        if cols < 2 or rows < 2 or cols * rows < 6:
            raise CalibrationError(f"board of {cols}x{rows} squares is too small: use at least 3x3")
        if not 0 < self.marker_m < self.square_m:
            raise CalibrationError(
                f"board marker side {self.marker_m} m must be positive and smaller than the square side "
                f"{self.square_m} m: measure the printed board and fix the sizes"
            )
        if not hasattr(cv2.aruco, self.dictionary):
            raise CalibrationError(f"unknown ArUco dictionary {self.dictionary!r}: use e.g. DICT_4X4_50, "
                                       "DICT_5X5_100 or DICT_6X6_250")
        markers = (cols * rows) // 2
        if markers > cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary)).bytesList.shape[0]:
            raise CalibrationError(f"{self.dictionary} has fewer than the {markers} markers a {cols}x{rows} "
                                       "board needs: choose a larger dictionary")

    @property
    def size_m(self) -> tuple[float, float]:
        """Printed (width, height) of the squares area."""
        return self.squares[0] * self.square_m, self.squares[1] * self.square_m

    @property
    def center_m(self) -> np.ndarray:
        """Centre of the squares area in the board frame (origin at a corner, z out of the face)."""
        w, h = self.size_m
        return np.array([w / 2, h / 2, 0.0])

    def describe(self) -> str:
        """The parameters a user must give the calibration commands, as printed on the page."""
        legacy = ", legacy pattern" if self.legacy else ""
        return (f"ChArUco {self.squares[0]}x{self.squares[1]} squares of {self.square_m * 1e3:g} mm, markers "
                f"{self.marker_m * 1e3:g} mm, {self.dictionary}{legacy}. Print at 100 % and measure a square.")

    def board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        board = cv2.aruco.CharucoBoard(tuple(self.squares), self.square_m, self.marker_m, dictionary)
        board.setLegacyPattern(self.legacy)
        return board


def render_board(cfg: BoardConfig, px_per_m: float, margin_m: float = 0.01) -> np.ndarray:
    """The board as a grey uint8 image at `px_per_m`, with a white quiet zone of `margin_m` all round."""
    w, h = cfg.size_m
    margin = round(margin_m * px_per_m)
    size = (round(w * px_per_m) + 2 * margin, round(h * px_per_m) + 2 * margin)
    return cfg.board().generateImage(size, marginSize=margin, borderBits=1)


def page_m(cfg: BoardConfig) -> tuple[float, float]:
    """(width, height) of the board's page: SHEET_M (turned for a landscape board) when the board, a QUIET_M white
    border and the parameters' line fit inside the printers' margins, else just large enough for them."""
    w, h = (v + 2 * (PRINT_MARGIN_M + QUIET_M) for v in cfg.size_m)
    sheet = SHEET_M if cfg.size_m[1] >= cfg.size_m[0] else SHEET_M[::-1]
    return max(w, sheet[0]), max(h + TEXT_M, sheet[1])


def fits_a4_and_letter(cfg: BoardConfig) -> bool:
    return sorted(page_m(cfg)) == sorted(SHEET_M)


def render_page(cfg: BoardConfig, dpi: float) -> np.ndarray:
    """The printable page as a grey uint8 image at `dpi`: the board centred, its parameters
    (`BoardConfig.describe`) on one line QUIET_M under it."""
    px_per_m = dpi / INCH_M
    w, h = page_m(cfg)
    page = Image.new("L", (round(w * px_per_m), round(h * px_per_m)), 255)
    board = Image.fromarray(render_board(cfg, px_per_m, 0.0))
    gap, text_px = round(QUIET_M * px_per_m), round(TEXT_M * px_per_m)
    left, top = (page.width - board.width) // 2, (page.height - board.height - gap - text_px) // 2
    page.paste(board, (left, top))
    draw = ImageDraw.Draw(page)
    text, size = cfg.describe(), text_px
    font = ImageFont.load_default(size=size)
    while size > 4 and draw.textlength(text, font=font) > page.width - 2 * PRINT_MARGIN_M * px_per_m:
        size -= 1
        font = ImageFont.load_default(size=size)
    draw.text((page.width / 2, top + board.height + gap), text, fill=0, font=font, anchor="mt")
    return np.asarray(page)


def write_board(cfg: BoardConfig, path: str | Path, dpi: float = 300.0, overwrite: bool = False) -> Path:
    """Write the printable page (`render_page`) as PNG (dpi stored) or PDF (its page at true scale); an existing
    file only with `overwrite`.

    Print at 100 % ("actual size", no fit-to-page), then measure a square: `square_m` must match it.
    """
    path = Path(path)
    if path.suffix.lower() not in (".png", ".pdf"):
        raise CalibrationError(f"board output {path} must end in .png or .pdf")
    if not path.parent.is_dir():
        raise CalibrationError(f"folder {path.parent} does not exist: create it or choose another --out")
    if path.exists() and not overwrite:
        raise CalibrationError(f"{path} already exists: pass --overwrite to replace it, or choose another --out")
    page = sorted(v + 2 * QUIET_M for v in cfg.size_m)
    if page[0] > MAX_PAGE_M[0] or page[1] > MAX_PAGE_M[1]:
        raise CalibrationError(
            f"a {cfg.squares[0]}x{cfg.squares[1]} board of {cfg.square_m * 1e3:g} mm squares is {page[0] * 1e3:.0f} x "
            f"{page[1] * 1e3:.0f} mm, larger than an A0 sheet ({MAX_PAGE_M[0] * 1e3:.0f} x {MAX_PAGE_M[1] * 1e3:.0f} "
            "mm): use a smaller --square-mm or fewer --squares")
    side_px = max(page_m(cfg)) * dpi / INCH_M
    if side_px > MAX_SIDE_PX:
        raise CalibrationError(f"at --dpi {dpi:g} the board is {side_px:.0f} px long, more than the {MAX_SIDE_PX} px "
                               f"limit: use --dpi {MAX_SIDE_PX * INCH_M / max(page_m(cfg)):.0f} or less")
    image = Image.fromarray(render_page(cfg, dpi))
    partial = path.with_name(f".{path.name}.partial")  # an existing file is replaced only once the new one is whole
    if path.suffix.lower() == ".pdf":
        image.save(partial, "PDF", resolution=dpi)
    else:
        image.save(partial, "PNG", dpi=(dpi, dpi))
    partial.replace(path)
    return path
