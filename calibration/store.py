"""Calibration files: one per camera serial and robot id, OpenCV FileStorage YAML (or JSON), so that
`cv2.FileStorage(path, cv2.FILE_STORAGE_READ).getNode("T_camera").mat()` reads them from any language.

Hand-eye file `<dir>/handeye_<robot_id>_<serial>.yaml`; intrinsics file `<dir>/intrinsics_<serial>.yaml`.
`<dir>` is $AXISLOOP_CALIBRATION_DIR, default ~/.config/axisloop/calibration.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import cv2
import numpy as np

from calibration.board import BoardConfig
from calibration.intrinsics import MAX_FACTORY_OFFSET, factory_offset
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

FORMAT_VERSION = 1
SETUP_NAMES = ("eye-to-hand", "eye-in-hand")


def default_dir() -> Path:
    return Path(os.environ.get("AXISLOOP_CALIBRATION_DIR", Path.home() / ".config" / "axisloop" / "calibration"))


def _slug(text: str, what: str) -> str:
    if not text or not re.fullmatch(r"[A-Za-z0-9._-]+", text):
        raise CalibrationError(f"{what} {text!r} cannot name a calibration file: use letters, digits, . _ -")
    return text


def hand_eye_path(serial: str, robot_id: str, directory: str | Path | None = None) -> Path:
    base = Path(directory) if directory is not None else default_dir()
    return base / f"handeye_{_slug(robot_id, 'robot id')}_{_slug(serial, 'camera serial')}.yaml"


def intrinsics_path(serial: str, directory: str | Path | None = None) -> Path:
    base = Path(directory) if directory is not None else default_dir()
    return base / f"intrinsics_{_slug(serial, 'camera serial')}.yaml"


@dataclass(frozen=True)
class HandEyeRecord:
    """A stored hand-eye calibration.

    T_camera: eye-to-hand T_base_camera; eye-in-hand T_tool_camera (tool = `tool_frame`). T_board: eye-to-hand
    T_tool_board; eye-in-hand T_base_board. Residuals: RMS reprojection (px), spread of the base-fixed frame
    over the samples (mm, deg). `created` is timezone-aware UTC.
    """

    camera_serial: str
    robot_id: str
    setup: str
    method: str
    T_camera: np.ndarray
    T_board: np.ndarray
    tool_frame: str
    intrinsics: Intrinsics
    distortion: np.ndarray
    reprojection_px: float
    spread_mm: float
    spread_deg: float
    samples: int
    board: BoardConfig
    created: datetime = field(default_factory=lambda: datetime.now(timezone.utc))

    def T_base_camera(self, T_base_tool: np.ndarray | None = None) -> np.ndarray:
        """The camera pose in the base: fixed (eye-to-hand) or at the given tool pose (eye-in-hand)."""
        if self.setup == "eye-to-hand":
            return self.T_camera.copy()
        if T_base_tool is None:
            raise CalibrationError("an eye-in-hand camera's pose needs the current tool pose (forward kinematics)")
        return np.asarray(T_base_tool, float) @ self.T_camera

    def age_days(self, now: datetime | None = None) -> float:
        return ((now or datetime.now(timezone.utc)) - self.created).total_seconds() / 86400.0


@dataclass(frozen=True)
class IntrinsicsRecord:
    """Stored intrinsics of one camera: pinhole, distortion (k1 k2 p1 p2 k3), RMS reprojection error, views."""

    camera_serial: str
    intrinsics: Intrinsics
    distortion: np.ndarray
    rms_px: float
    views: int
    created: datetime = field(default_factory=lambda: datetime.now(timezone.utc))


def save_hand_eye(record: HandEyeRecord, directory: str | Path | None = None, path: Path | None = None) -> Path:
    """Write the record to its file (or `path`, .yaml or .json); returns the path."""
    path = path or hand_eye_path(record.camera_serial, record.robot_id, directory)
    with _writer(path) as fs:
        for key in ("camera_serial", "robot_id", "setup", "method", "tool_frame"):
            fs.write(key, getattr(record, key))
        fs.write("T_camera", record.T_camera)
        fs.write("T_board", record.T_board)
        _write_intrinsics(fs, record.intrinsics, record.distortion)
        for key in ("reprojection_px", "spread_mm", "spread_deg"):
            fs.write(key, float(getattr(record, key)))
        fs.write("samples", int(record.samples))
        b = record.board
        fs.write("board_squares", np.array(b.squares, np.int32))
        fs.write("board_square_m", b.square_m)
        fs.write("board_marker_m", b.marker_m)
        fs.write("board_dictionary", b.dictionary)
        fs.write("board_legacy", int(b.legacy))
    return path


def load_hand_eye(path: str | Path) -> HandEyeRecord:
    """Read and validate a hand-eye file; CalibrationError naming the file and what is wrong."""
    path = Path(path)
    with _reader(path) as r:
        setup = r.string("setup")
        if setup not in SETUP_NAMES:
            raise CalibrationError(f"calibration file {path}: setup {setup!r} is not one of {SETUP_NAMES}: redo it")
        squares = r.mat("board_squares", (2,)).astype(int)
        try:
            board = BoardConfig((int(squares[0]), int(squares[1])), r.real("board_square_m"), r.real("board_marker_m"),
                                r.string("board_dictionary"), bool(r.real("board_legacy")))
        except CalibrationError as exc:
            raise CalibrationError(f"calibration file {path}: {exc}") from exc
        except (ValueError, TypeError, OverflowError, cv2.error) as exc:  # a value OpenCV cannot make a board of
            raise r._bad(f"has a board OpenCV cannot build ({exc})") from exc
        return HandEyeRecord(
            camera_serial=r.string("camera_serial"), robot_id=r.string("robot_id"), setup=setup,
            method=r.string("method"), T_camera=r.pose("T_camera"), T_board=r.pose("T_board"),
            tool_frame=r.string("tool_frame"), intrinsics=r.intrinsics(), distortion=r.mat("distortion", (5,)),
            reprojection_px=r.real("reprojection_px"), spread_mm=r.real("spread_mm"),
            spread_deg=r.real("spread_deg"), samples=int(r.real("samples")), board=board, created=r.created(),
        )


def load_for(serial: str, robot_id: str, directory: str | Path | None = None) -> HandEyeRecord | None:
    """The hand-eye calibration of this camera and robot (what `deploy open-*` loads), None if there is none.

    Raises CalibrationError when the file is corrupt or was written for another camera or robot.
    """
    path = hand_eye_path(serial, robot_id, directory)
    if not path.is_file():
        return None
    record = load_hand_eye(path)
    if (record.camera_serial, record.robot_id) != (serial, robot_id):
        raise CalibrationError(
            f"calibration file {path} holds camera {record.camera_serial!r} on robot {record.robot_id!r}, not "
            f"camera {serial!r} on robot {robot_id!r}: it was copied or renamed; replace it with `deploy calibrate "
            "hand-eye --existing redo`"
        )
    return record


def save_intrinsics(record: IntrinsicsRecord, directory: str | Path | None = None) -> Path:
    path = intrinsics_path(record.camera_serial, directory)
    with _writer(path) as fs:
        fs.write("camera_serial", record.camera_serial)
        _write_intrinsics(fs, record.intrinsics, record.distortion)
        fs.write("rms_px", float(record.rms_px))
        fs.write("views", int(record.views))
    return path


def load_intrinsics_for(serial: str, directory: str | Path | None = None,
                        factory: Intrinsics | None = None) -> IntrinsicsRecord | None:
    """This camera's own intrinsics if `deploy calibrate intrinsics` made them, else None (factory values).
    CalibrationError when the file is for another camera or (given its `factory` values) too far from them."""
    path = intrinsics_path(serial, directory)
    if not path.is_file():
        return None
    with _reader(path) as r:
        record = IntrinsicsRecord(r.string("camera_serial"), r.intrinsics(), r.mat("distortion", (5,)),
                                  r.real("rms_px"), int(r.real("views")), r.created())
    if record.camera_serial != serial:
        raise CalibrationError(f"intrinsics file {path} is for camera {record.camera_serial!r}, not {serial!r}: "
                               "replace it with `deploy calibrate intrinsics --existing redo`, or delete it to use "
                               "the factory values")
    offset = factory and factory_offset(record.intrinsics, factory)
    if offset:
        raise CalibrationError(f"intrinsics file {path} has {offset} (factory), more than {MAX_FACTORY_OFFSET:.0%} "
                               "off, so distances solved with it would be off too: delete it to use the factory "
                               "values, or redo it with `deploy calibrate intrinsics --existing redo`")
    return record


def _write_intrinsics(fs: cv2.FileStorage, intrinsics: Intrinsics, distortion: np.ndarray) -> None:
    fs.write("image_width", int(intrinsics.width))
    fs.write("image_height", int(intrinsics.height))
    fs.write("camera_matrix", intrinsics.K)
    fs.write("distortion", np.asarray(distortion, float).reshape(1, -1))


class _writer:
    """FileStorage for writing, with format version and date, closed on exit; the parent folder is created."""

    def __init__(self, path: Path) -> None:
        if path.suffix not in (".yaml", ".yml", ".json"):
            raise CalibrationError(f"calibration file {path} must end in .yaml or .json")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)

    def __enter__(self) -> cv2.FileStorage:
        self.fs.write("format_version", FORMAT_VERSION)
        self.fs.write("created", datetime.now(timezone.utc).isoformat(timespec="seconds"))
        return self.fs

    def __exit__(self, *exc) -> None:
        self.fs.release()


class _reader:
    """Typed reads from a FileStorage; every failure names the file, the key and the fix."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if not path.is_file():
            raise CalibrationError(f"calibration file {path} does not exist: run `deploy calibrate` first")
        try:
            self.fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        except (cv2.error, SystemError) as exc:  # OpenCV 5's binding raises SystemError on a parse error
            raise self._bad("is not a readable OpenCV YAML/JSON file") from exc
        if not self.fs.isOpened():
            raise self._bad("is not a readable OpenCV YAML/JSON file")
        if self.real("format_version") != FORMAT_VERSION:
            raise self._bad(f"has format version {self.real('format_version'):g}, expected {FORMAT_VERSION}")

    def __enter__(self) -> _reader:
        return self

    def __exit__(self, *exc) -> None:
        self.fs.release()

    def _bad(self, what: str) -> CalibrationError:
        return CalibrationError(f"calibration file {self.path} {what}: delete it and calibrate again")

    def _node(self, key: str) -> cv2.FileNode:
        node = self.fs.getNode(key)
        if node.empty():
            raise self._bad(f"has no {key!r}")
        return node

    def string(self, key: str) -> str:
        node = self._node(key)
        if not node.isString():
            raise self._bad(f"has a non-text {key!r}")
        return node.string()

    def real(self, key: str) -> float:
        node = self._node(key)
        if not node.isReal() and not node.isInt():
            raise self._bad(f"has a non-numeric {key!r}")
        value = float(node.real())
        if not np.isfinite(value):
            raise self._bad(f"has a non-finite {key!r}")
        return value

    def mat(self, key: str, shape: tuple[int, ...]) -> np.ndarray:
        node = self._node(key)
        value = node.mat() if node.isMap() else None  # an OpenCV matrix is a map (rows, cols, dt, data)
        wrong_shape = value is None or (value.shape != shape if len(shape) == 2 else value.size != shape[0])
        if wrong_shape or not np.all(np.isfinite(value)):
            raise self._bad(f"has a malformed {key!r} (expected {shape} finite numbers)")
        return np.asarray(value, float).reshape(shape)

    def pose(self, key: str) -> np.ndarray:
        T = self.mat(key, (4, 4))
        R = T[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0 or np.abs(T[3] - [0, 0, 0, 1]).max() > 0:
            raise self._bad(f"has a {key!r} that is not a rigid transform")
        return T

    def intrinsics(self) -> Intrinsics:
        K = self.mat("camera_matrix", (3, 3))
        w, h = int(self.real("image_width")), int(self.real("image_height"))
        if w <= 0 or h <= 0 or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise self._bad("has invalid intrinsics")
        return Intrinsics(w, h, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))

    def created(self) -> datetime:
        try:
            created = datetime.fromisoformat(self.string("created"))
        except ValueError as exc:
            raise self._bad("has an unreadable 'created' date") from exc
        return created if created.tzinfo else created.replace(tzinfo=timezone.utc)
