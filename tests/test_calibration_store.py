"""Calibration files: OpenCV-readable round trip, one per camera serial and robot id, corrupt or mismatched
files rejected with a clear message, age and serial warnings."""

from datetime import datetime, timedelta, timezone

import cv2
import numpy as np
import pytest

from calibration.board import BoardConfig
from calibration.check import staleness_warnings
from calibration.store import (
    HandEyeRecord,
    IntrinsicsRecord,
    hand_eye_path,
    load_for,
    load_hand_eye,
    load_intrinsics_for,
    save_hand_eye,
    save_intrinsics,
)
from calibration.transforms import from_rt
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError


def record(serial: str = "123456", robot_id: str = "panda", **changes) -> HandEyeRecord:
    values = dict(
        camera_serial=serial, robot_id=robot_id, setup="eye-in-hand", method="park+refined",
        T_camera=from_rt([0.1, -0.2, 0.3], [0.05, 0.0, -0.09]), T_board=from_rt([3.1, 0.0, 0.2], [0.5, -0.2, 0.0]),
        tool_frame="panda_grasptarget", intrinsics=Intrinsics.from_fov(640, 480, 65.0),
        distortion=np.array([0.01, -0.02, 0.0, 0.0, 0.003]), reprojection_px=0.31, spread_mm=0.9, spread_deg=0.27,
        samples=15, board=BoardConfig((5, 6), legacy=True),
    )
    return HandEyeRecord(**(values | changes))


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_round_trip_keeps_every_field(tmp_path, suffix):
    original = record()
    path = save_hand_eye(original, path=tmp_path / f"calib{suffix}")
    loaded = load_hand_eye(path)
    assert np.allclose(loaded.T_camera, original.T_camera, atol=1e-12)
    assert np.allclose(loaded.T_board, original.T_board, atol=1e-12)
    assert np.allclose(loaded.distortion, original.distortion)
    assert loaded.intrinsics == original.intrinsics and loaded.board == original.board
    for key in ("camera_serial", "robot_id", "setup", "method", "tool_frame", "samples"):
        assert getattr(loaded, key) == getattr(original, key)
    assert loaded.reprojection_px == pytest.approx(0.31) and loaded.spread_deg == pytest.approx(0.27)
    assert abs((loaded.created - datetime.now(timezone.utc)).total_seconds()) < 60


def test_opencv_reads_the_matrices(tmp_path):
    path = save_hand_eye(record(), tmp_path)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.allclose(fs.getNode("T_camera").mat(), record().T_camera)
    assert fs.getNode("camera_matrix").mat().shape == (3, 3)
    assert fs.getNode("samples").real() == 15
    fs.release()


def test_one_file_per_serial_and_robot(tmp_path):
    save_hand_eye(record("A1"), tmp_path)
    save_hand_eye(record("B2", robot_id="ur5", setup="eye-to-hand"), tmp_path)
    assert load_for("A1", "panda", tmp_path).camera_serial == "A1"
    assert load_for("B2", "ur5", tmp_path).setup == "eye-to-hand"
    assert load_for("A1", "ur5", tmp_path) is None  # never calibrated: the caller falls back or asks
    assert hand_eye_path("A1", "panda", tmp_path) != hand_eye_path("B2", "panda", tmp_path)


def test_eye_in_hand_camera_pose_follows_the_tool():
    r = record()
    T_tool = from_rt([0.0, 0.5, 0.0], [0.4, 0.0, 0.5])
    assert np.allclose(r.T_base_camera(T_tool), T_tool @ r.T_camera)
    with pytest.raises(CalibrationError, match="needs the current tool pose"):
        r.T_base_camera()


def test_file_of_another_camera_is_rejected(tmp_path):
    path = save_hand_eye(record("A1"), tmp_path)
    path.rename(hand_eye_path("C3", "panda", tmp_path))
    with pytest.raises(CalibrationError, match="holds camera 'A1'.*not camera 'C3'"):
        load_for("C3", "panda", tmp_path)


@pytest.mark.parametrize("damage, message", [
    (lambda text: "this is { not yaml :::\n", "not a readable OpenCV"),
    (lambda text: text.replace("setup: eye-in-hand", "setup: eye-on-head"), "setup 'eye-on-head'"),
    (lambda text: text.replace("format_version: 1", "format_version: 7"), "format version 7"),
    (lambda text: "\n".join(line for line in text.splitlines() if not line.startswith("robot_id")), "no 'robot_id'"),
    (lambda text: text.replace("samples: 15", "samples: many"), "non-numeric 'samples'"),
    (lambda text: text.replace("rows: 4\n   cols: 4", "rows: 2\n   cols: 8", 1), "malformed 'T_camera'"),
    (lambda text: text.replace("created: \"", "created: \"yesterday"), "unreadable 'created'"),
    (lambda text: text.replace("board_dictionary: DICT_4X4_50", "board_dictionary: DICT_9X9"), "unknown ArUco"),
])
def test_corrupt_files_are_rejected(tmp_path, damage, message):
    path = save_hand_eye(record(), tmp_path)
    path.write_text(damage(path.read_text()))
    with pytest.raises(CalibrationError, match=message):
        load_for("123456", "panda", tmp_path)


def test_non_rigid_transform_is_rejected(tmp_path):
    bad = record(T_camera=np.diag([1.0, 2.0, 1.0, 1.0]))
    path = save_hand_eye(bad, tmp_path)
    with pytest.raises(CalibrationError, match="not a rigid transform"):
        load_hand_eye(path)


def test_bad_names_and_suffixes(tmp_path):
    with pytest.raises(CalibrationError, match="camera serial"):
        hand_eye_path("../etc", "panda", tmp_path)
    with pytest.raises(CalibrationError, match=r"\.yaml or \.json"):
        save_hand_eye(record(), path=tmp_path / "calib.txt")
    with pytest.raises(CalibrationError, match="does not exist"):
        load_hand_eye(tmp_path / "nothing.yaml")


def test_intrinsics_file(tmp_path):
    assert load_intrinsics_for("123456", tmp_path) is None
    K = Intrinsics(640, 480, 610.0, 611.0, 321.0, 239.0)
    save_intrinsics(IntrinsicsRecord("123456", K, np.zeros(5), 0.2, 12), tmp_path)
    loaded = load_intrinsics_for("123456", tmp_path)
    assert loaded.intrinsics == K and loaded.views == 12


def test_age_and_serial_warnings():
    r = record()
    now = r.created + timedelta(days=45)
    warnings = staleness_warnings(r, "999", max_age_days=30, now=now)
    assert any("45 days old" in w for w in warnings)
    assert any("made with camera 123456, this is 999" in w for w in warnings)
    assert staleness_warnings(r, "123456", max_age_days=30, now=r.created + timedelta(days=1)) == []
