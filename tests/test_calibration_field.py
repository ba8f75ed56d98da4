"""The field audit of `deploy calibrate`: own intrinsics that made hand-eye 20x worse, files overwritten or
reused unasked, questions nobody can answer, conflicts found only after the arm moved, fixes that repeat the
error, an over-size board. Simulated rig (PyBullet Panda, simulated D415) and synthetic board views."""

import io
import json

import cv2
import numpy as np
import pytest

from calibration.board import BoardConfig
from calibration.check import staleness_warnings
from calibration.detect import BoardView
from calibration.intrinsics import calibrate_intrinsics, compare_with_factory
from calibration.store import HandEyeRecord, IntrinsicsRecord, hand_eye_path, save_hand_eye, save_intrinsics
from calibration.transforms import from_rt
from deploy.cli import main
from drivers.camera.base import Intrinsics
from drivers.errors import CalibrationError

FACTORY = Intrinsics.from_fov(640, 480, 65.0)  # the simulated D415's, exact in simulation
BOARD = BoardConfig()
POINTS = np.asarray(BOARD.board().getChessboardCorners(), float)
# what `deploy calibrate intrinsics` saved in the field audit: fx 2.3 % low, k3 = -52
AUDIT = IntrinsicsRecord("sim-d415", Intrinsics(640, 480, 490.84, 490.04, 313.52, 250.85),
                         np.array([0.117, 0.433, 0.0106, -0.0096, -52.18]), 0.35, 12)


def run(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def error_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("error:")]


def record(setup: str = "eye-to-hand", robot_id: str = "panda-sim", intrinsics: Intrinsics = FACTORY) -> HandEyeRecord:
    return HandEyeRecord("sim-d415", robot_id, setup, "park+refined", from_rt([0.1, -0.2, 0.3], [0.4, -0.6, 0.7]),
                         from_rt([3.1, 0.0, 0.2], [0.0, 0.0, 0.03]), "panda_grasptarget", intrinsics, np.zeros(5),
                         0.3, 1.0, 0.1, 15, BOARD)


def synthetic_views(camera: Intrinsics, n: int = 12, sigma_px: float = 0.1, seed: int = 0) -> list[BoardView]:
    """Board views of a pinhole `camera` 0.5 m away, tilted 20-40 deg about axes stepping by the golden angle,
    spread over the image, with Gaussian corner noise."""
    rng = np.random.default_rng(seed)
    views = []
    for i in range(n):
        phi = i * np.pi * (3 - np.sqrt(5))
        rvec = np.radians(rng.uniform(20, 40)) * np.array([np.cos(phi), np.sin(phi), 0.0])
        R = cv2.Rodrigues(rvec)[0]
        t = np.array([rng.uniform(-0.08, 0.08), rng.uniform(-0.04, 0.04), 0.5]) - R @ BOARD.center_m
        px = cv2.projectPoints(POINTS, rvec, t, camera.K, None)[0].reshape(-1, 2)
        views.append(BoardView(px + rng.normal(0.0, sigma_px, px.shape), np.arange(len(POINTS)), POINTS))
    return views


def scaled(camera: Intrinsics, factor: float) -> Intrinsics:
    return Intrinsics(camera.width, camera.height, camera.fx * factor, camera.fy * factor, camera.cx, camera.cy)


# --- finding 1: own intrinsics -----------------------------------------------------------------------------------


def test_eye_to_hand_own_intrinsics_are_refused_and_hand_eye_keeps_its_accuracy(capsys, tmp_path):
    code, _, err = run(capsys, "calibrate", "intrinsics", "--dir", tmp_path)
    assert code == 2 and "intrinsics not saved: 12 views fix fx only to" in err and len(error_lines(err)) == 1
    assert not list(tmp_path.iterdir())
    code, out, _ = run(capsys, "calibrate", "hand-eye", "--dir", tmp_path, "--json")
    data = json.loads(out)
    assert code == 0 and data["intrinsics_from"] == "factory" and data["true_error_mm"] < 1.5  # 17.3 mm before


def test_eye_in_hand_own_intrinsics_confirm_the_factory_values_and_redo_removes_the_old_file(capsys, tmp_path):
    save_intrinsics(IntrinsicsRecord("sim-d415", scaled(FACTORY, 1.01), np.zeros(5), 0.3, 12), tmp_path)
    code, out, _ = run(capsys, "calibrate", "intrinsics", "--setup", "eye-in-hand", "--existing", "redo", "--dir",
                       tmp_path, "--json")
    data = json.loads(out)
    assert code == 0 and data["saved"] is False and data["removed_old_file"] is True
    assert data["fx"] == pytest.approx(FACTORY.fx, abs=3 * data["std"]["fx"]) and data["distortion"][2:] == [0, 0, 0]
    assert not list(tmp_path.iterdir())
    code, out, _ = run(capsys, "calibrate", "hand-eye", "--setup", "eye-in-hand", "--dir", tmp_path, "--json")
    data = json.loads(out)
    assert code == 0 and data["intrinsics_from"] == "factory" and data["true_error_mm"] < 1.5  # 5.7 mm before


def test_a_fit_replaces_the_factory_values_only_when_they_are_measurably_wrong():
    agrees = calibrate_intrinsics(synthetic_views(FACTORY), 640, 480, FACTORY)
    assert compare_with_factory(agrees, FACTORY) is False
    assert agrees.distortion[2:].tolist() == [0.0, 0.0, 0.0]  # k3, p1, p2 are not fitted
    truth = scaled(FACTORY, 1.01)  # a camera whose factory focal length is 1 % off
    differs = calibrate_intrinsics(synthetic_views(truth), 640, 480, FACTORY)
    assert compare_with_factory(differs, FACTORY) is True
    assert differs.intrinsics.fx == pytest.approx(truth.fx, abs=3 * differs.std[0])
    far = calibrate_intrinsics(synthetic_views(scaled(FACTORY, 1.03)), 640, 480, FACTORY)
    with pytest.raises(CalibrationError, match="fx .* differ from the camera's factory values by more than 2%"):
        compare_with_factory(far, FACTORY)
    views = synthetic_views(FACTORY)
    views[4] = BoardView(views[4].pixels + np.random.default_rng(1).normal(0, 3.0, views[4].pixels.shape),
                         views[4].ids, views[4].points)
    with pytest.raises(CalibrationError, match="view 5 of 12 has a reprojection error"):
        compare_with_factory(calibrate_intrinsics(views, 640, 480, FACTORY), FACTORY)


def test_an_old_far_off_intrinsics_file_is_refused_before_the_arm_moves(capsys, tmp_path, opened):
    save_intrinsics(AUDIT, tmp_path)
    code, _, err = run(capsys, "calibrate", "hand-eye", "--existing", "redo", "--dir", tmp_path)
    assert code == 2 and "intrinsics_sim-d415.yaml has fx 490.8 vs 502.3" in err and "delete it" in err
    assert opened[-1].rig.world.clock.steps == 0 and not hand_eye_path("sim-d415", "panda-sim", tmp_path).exists()
    warnings = staleness_warnings(record(intrinsics=AUDIT.intrinsics), "sim-d415", 30.0, factory=FACTORY)
    assert any("intrinsics whose fx 490.8 vs 502.3" in w for w in warnings)
    assert staleness_warnings(record(), "sim-d415", 30.0, factory=FACTORY) == []


# --- findings 2-4: existing files --------------------------------------------------------------------------------


def test_intrinsics_reuse_an_existing_file_and_never_overwrite_it_unasked(capsys, tmp_path, monkeypatch):
    path = save_intrinsics(IntrinsicsRecord("sim-d415", FACTORY, np.zeros(5), 0.3, 12), tmp_path)
    before = path.read_bytes()
    code, out, _ = run(capsys, "calibrate", "intrinsics", "--existing", "reuse", "--dir", tmp_path, "--json")
    assert code == 0 and json.loads(out) == {"file": str(path), "reused": True}
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # as </dev/null
    code, _, err = run(capsys, "calibrate", "intrinsics", "--yes", "--dir", tmp_path)
    assert code == 2 and "pass --existing reuse or --existing redo" in error_lines(err)[0]
    assert path.read_bytes() == before


def test_hand_eye_never_reuses_a_file_of_another_setup_and_names_existing_when_nobody_answers(
        capsys, tmp_path, monkeypatch, opened):
    path = save_hand_eye(record("eye-to-hand"), tmp_path)
    code, _, err = run(capsys, "calibrate", "hand-eye", "--setup", "eye-in-hand", "--existing", "reuse", "--dir",
                       tmp_path)
    assert code == 2 and len(error_lines(err)) == 1
    assert "holds an eye-to-hand calibration, not eye-in-hand: pass --existing redo" in err
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    code, _, err = run(capsys, "calibrate", "hand-eye", "--yes", "--dir", tmp_path)
    assert code == 2 and "pass --existing reuse or --existing redo" in err and "--yes to skip" not in err
    assert all(dev.rig.world.clock.steps == 0 for dev in opened) and load_setup(path) == "eye-to-hand"


def load_setup(path) -> str:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        return fs.getNode("setup").string()
    finally:
        fs.release()


# --- finding 5: conflicts known before the arm moves ------------------------------------------------------------


@pytest.mark.parametrize(("args", "message"), [
    (("intrinsics", "--poses", "3"), "--poses 3 is too few: intrinsics needs at least 4"),
    (("hand-eye", "--poses", "2"), "--poses 2 is too few: hand-eye needs at least 3"),
    (("check", "--poses", "1"), "--poses 1 is too few: check needs at least 2"),
])
def test_too_few_poses_are_refused_before_any_device_opens(capsys, tmp_path, opened, args, message):
    code, _, err = run(capsys, "calibrate", *args, "--dir", tmp_path)
    assert code == 2 and message in err and opened == []


def test_pointing_on_an_eye_to_hand_calibration_is_refused_before_the_arm_moves(capsys, tmp_path, opened):
    save_hand_eye(record("eye-to-hand"), tmp_path)
    code, _, err = run(capsys, "calibrate", "check", "--arm", "sim-can", "--point", "--dir", tmp_path)
    (dev,) = opened
    assert code == 2 and "--point is for eye-in-hand" in err and dev.rig.world.clock.steps == 0
    assert all(m.mit_frames == 0 for m in dev.motors.motors)


# --- findings 6, 7 -----------------------------------------------------------------------------------------------


def test_the_fix_for_a_renamed_file_works_when_followed(capsys, tmp_path):
    save_hand_eye(record(robot_id="other"), path=hand_eye_path("sim-d415", "panda-sim", tmp_path))
    code, _, err = run(capsys, "calibrate", "hand-eye", "--poses", "4", "--dir", tmp_path)
    fix = "deploy calibrate hand-eye --existing redo"
    assert code == 2 and "holds camera 'sim-d415' on robot 'other'" in err and fix in err
    code, out, _ = run(capsys, "calibrate", "hand-eye", "--poses", "4", "--existing", "redo", "--dir", tmp_path,
                       "--json")
    assert code == 0 and json.loads(out)["samples"] == 4


@pytest.mark.parametrize(("args", "message"), [
    (("--square-mm", "1000"), "5006 x 7006 mm, larger than an A0 sheet (841 x 1189 mm): use a smaller --square-mm"),
    (("--dpi", "3000"), "at --dpi 3000 the board is 32953 px long, more than the 20000 px limit: use --dpi 1821"),
])
def test_an_over_size_board_is_one_line(capsys, tmp_path, args, message):
    code, _, err = run(capsys, "calibrate", "board", "--out", tmp_path / "board.pdf", *args)
    assert code == 2 and message in err and len(error_lines(err)) == 1 and not (tmp_path / "board.pdf").exists()


def test_board_refuses_to_overwrite_without_overwrite(capsys, tmp_path):
    out = tmp_path / "board.pdf"
    code, text, _ = run(capsys, "calibrate", "board", "--out", out, "--json")
    assert code == 0 and json.loads(text)["fits_a4_and_letter"] and out.exists()
    first = out.read_bytes()
    code, _, err = run(capsys, "calibrate", "board", "--out", out, "--square-mm", "30", "--marker-mm", "22")
    assert code == 2 and len(error_lines(err)) == 1 and "already exists: pass --overwrite" in err
    assert out.read_bytes() == first
    code, _, _ = run(capsys, "calibrate", "board", "--out", out, "--square-mm", "30", "--marker-mm", "22",
                     "--overwrite")
    assert code == 0 and out.read_bytes() != first
