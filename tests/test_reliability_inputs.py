"""Property-based: random bytes and random values fed to every file reader (frames recording meta.json and
frames.jsonl, robot TOML, run config TOML, calibration YAML, trajectory files) and to the CAN frame parser end in
the reader's own one-line error (or a valid result), never in another exception."""

import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calibration.store import load_hand_eye, load_intrinsics_for
from deploy.cli import main
from deploy.config import load_config
from deploy.errors import ConfigError
from drivers.arm.damiao import (
    MODELS,
    FrameError,
    is_param_reply,
    unpack_feedback,
    unpack_mit,
    unpack_param_reply,
    unpack_param_request,
)
from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesReplayCamera, FramesWriter
from drivers.errors import ArmError, CalibrationError, CameraError, RecordingError

FUZZ = settings(max_examples=40, deadline=None, database=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
REALS = st.floats(allow_nan=True, allow_infinity=True) | st.integers(-10**20, 10**20)
NUMBERS = REALS | st.booleans()
JSON_VALUES = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner,
                                                                                         max_size=5), max_leaves=20)
BYTES = st.binary(max_size=600)


def _recording(path: Path, frames: int = 2) -> Path:
    """A valid 8x6 frames recording with `frames` frames."""
    intr = Intrinsics(8, 6, 10.0, 10.0, 4.0, 3.0)
    with FramesWriter(path, intr) as writer:
        for i in range(frames):
            writer.write(Frame(i, 0.1 * i, np.full((6, 8, 3), 80, np.uint8), np.full((6, 8), 1.0, np.float32),
                               intr), joint_positions=[0.1, 0.2], ee_pose=np.eye(4))
    return path


def _read_all(path: Path) -> None:
    """Open a recording and read every frame, as replay and `axis estimate` do."""
    recording = FramesRecording(path)
    for i in range(len(recording)):
        recording.frame(i)


# --- frames recordings -----------------------------------------------------------------------------------------


@FUZZ
@given(data=BYTES)
def test_meta_json_of_random_bytes_is_a_recording_error(tmp_path_factory, data):
    path = _recording(tmp_path_factory.mktemp("rec"))
    (path / "meta.json").write_bytes(data)
    with pytest.raises(RecordingError, match="meta.json"):
        FramesRecording(path)


@FUZZ
@given(field=st.sampled_from(["intrinsics", "depth_scale", "T_base_camera", "version", "format", "width", "fx",
                              "cx"]), value=JSON_VALUES)
def test_meta_json_with_random_values_opens_or_is_a_recording_error(tmp_path_factory, field, value):
    path = _recording(tmp_path_factory.mktemp("rec"))
    meta = json.loads((path / "meta.json").read_text())
    if field in ("width", "fx", "cx"):
        meta["intrinsics"][field] = value
    else:
        meta[field] = value
    (path / "meta.json").write_text(json.dumps(meta))
    try:
        recording = FramesRecording(path)
    except RecordingError:
        return
    intr = recording.intrinsics
    assert all(math.isfinite(v) for v in (intr.fx, intr.fy, intr.cx, intr.cy)) and recording.depth_scale > 0
    try:
        _read_all(path)
    except RecordingError:
        pass  # e.g. a width that no longer matches the PNGs


@FUZZ
@given(data=BYTES)
def test_frames_jsonl_of_random_bytes_reads_or_is_a_recording_error(tmp_path_factory, data):
    path = _recording(tmp_path_factory.mktemp("rec"))
    (path / "frames.jsonl").write_bytes(data)
    try:
        _read_all(path)
    except RecordingError as exc:
        assert "frames.jsonl" in str(exc) or ".png" in str(exc)


@FUZZ
@given(record=JSON_VALUES | st.fixed_dictionaries({"index": JSON_VALUES, "t": JSON_VALUES}),
       extra=st.sampled_from(["index", "t", "joint_positions", "ee_pose", "grasped"]), value=JSON_VALUES)
def test_frames_jsonl_with_random_records_reads_or_is_a_recording_error(tmp_path_factory, record, extra, value):
    path = _recording(tmp_path_factory.mktemp("rec"))
    good = json.loads((path / "frames.jsonl").read_text().splitlines()[0])
    changed = dict(good, **{extra: value})
    lines = [json.dumps(record, allow_nan=True), json.dumps(changed, allow_nan=True), json.dumps(good)]
    (path / "frames.jsonl").write_text("\n".join(lines) + "\n")
    try:
        recording = FramesRecording(path)
        records = recording.records
    except RecordingError:
        return
    for r in records:  # what the reader lets through is what consumers rely on
        assert isinstance(r["index"], int) and r["index"] >= 0 and math.isfinite(float(r["t"]))
        assert r.get("ee_pose") is None or np.isfinite(np.asarray(r["ee_pose"], float)).all()
        assert isinstance(r.get("grasped"), bool | None)


def test_a_damaged_png_in_a_replay_names_the_frame(tmp_path):
    path = _recording(tmp_path / "rec", frames=3)
    (path / "depth" / "000001.png").write_bytes(b"")
    camera = FramesReplayCamera(path)
    camera.connect()
    camera.read()
    with pytest.raises(CameraError, match=r"frame 1 is damaged: .*depth/000001.png is not a readable PNG"):
        camera.read()


# --- robot config, run config ----------------------------------------------------------------------------------


def _robot_fields(data: dict, prefix: str = "") -> list[str]:
    """Dotted names of every number in the stock robot config (lists by index)."""
    names = []
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            names += _robot_fields(value, name + ".")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for i, item in enumerate(value):
                names += _robot_fields(item, f"{name}.{i}.")
        elif isinstance(value, list):
            names += [f"{name}.{i}" for i, v in enumerate(value) if isinstance(v, (int, float))]
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            names.append(name)
    return names


STOCK = tomllib.loads(PANDA_SIM_CONFIG.read_text())
STOCK_NUMBERS = _robot_fields(STOCK)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(value)


def _robot_toml(field: str, value) -> str:
    """The stock robot config as TOML text with the number `field` set to `value`."""
    data = json.loads(json.dumps(STOCK))
    *parents, last = field.split(".")
    node = data
    for part in parents:
        node = node[int(part)] if part.isdigit() else node[part]
    node[int(last) if last.isdigit() else last] = value
    return _dump_toml(data)


def _dump_toml(data: dict) -> str:
    """Just enough TOML for a robot config: scalars and lists of scalars, tables, arrays of tables."""
    lines, tables = [], []
    for key, value in data.items():
        if isinstance(value, dict):
            tables.append((f"[{key}]", value))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            tables += [(f"[[{key}]]", item) for item in value]
        elif isinstance(value, list):
            lines.append(f"{key} = [{', '.join(_toml_value(v) for v in value)}]")
        else:
            lines.append(f"{key} = {json.dumps(value) if isinstance(value, str) else _toml_value(value)}")
    for header, table in tables:
        lines += ["", header] + [f"{k} = {json.dumps(v) if isinstance(v, str) else _toml_value(v)}"
                                 for k, v in table.items()]
    return "\n".join(lines) + "\n"


def test_the_toml_writer_of_these_tests_round_trips_the_stock_config(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_text(_dump_toml(STOCK))
    assert load_robot_config(path).model_dump(exclude={"source"}) == \
        load_robot_config(PANDA_SIM_CONFIG).model_dump(exclude={"source"})


@FUZZ
@given(data=BYTES)
def test_robot_toml_of_random_bytes_is_an_arm_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("robot") / "robot.toml"
    path.write_bytes(data)
    with pytest.raises(ArmError, match="robot config"):
        load_robot_config(path)


@FUZZ
@given(field=st.sampled_from(STOCK_NUMBERS), value=NUMBERS)
def test_robot_toml_with_random_numbers_loads_finite_or_is_an_arm_error(tmp_path_factory, field, value):
    path = tmp_path_factory.mktemp("robot") / "robot.toml"
    path.write_text(_robot_toml(field, value))
    try:
        config = load_robot_config(path)
    except ArmError as exc:
        assert "\n" not in str(exc)
        return
    numbers = _robot_fields(config.model_dump(exclude={"source"}))
    assert numbers  # the loaded config holds only finite numbers, safety limits included
    dumped = config.model_dump(exclude={"source"})
    for name in numbers:
        node = dumped
        for part in name.split("."):
            node = node[int(part)] if part.isdigit() else node[part]
        assert math.isfinite(node), name


@pytest.mark.parametrize(("field", "text"), [
    ("workspace_min", "[nan, nan, nan]"), ("workspace_max", "[0.9, inf, 1.25]"),
    ("watchdog.feedback_timeout_s", "inf"), ("watchdog.feedback_timeout_s", "5.0"),
    ("watchdog.reply_timeout_s", "nan"), ("joints.0.tau_max", "inf"), ("joints.2.q_min", "-inf"),
    ("q_ready", "[nan, 0, 0, 0, 0, 0, 0]"),
    # finite but absurd: each would switch its check off as surely as nan
    ("workspace_min", "[-1e9, -1e9, -1e9]"), ("workspace_max", "[0.9, 0.9, 1e9]"), ("workspace_min", "[-0.9, -3.5, 0]"),
    ("joints.0.a_max", "1e300"), ("joints.3.j_max", "1e300"), ("joints.0.tau_max", "1e300"),
    ("joints.4.tau_max", "28.5"), ("joints.0.v_max", "1e300"), ("joints.6.v_max", "8.5"), ("control_rate_hz", "1"),
    ("control_rate_hz", "99"),
])
def test_robot_configs_that_would_switch_a_safety_check_off_are_refused(tmp_path, field, text):
    path = tmp_path / "robot.toml"
    path.write_text(_robot_toml(field, "@@").replace('"@@"', text).replace("'@@'", text))
    with pytest.raises(ArmError, match=rf"robot config {re.escape(str(path))}: {re.escape(field)}"):
        load_robot_config(path)


@pytest.mark.parametrize(("field", "text"), [
    ("workspace_min", "[-3.0, -3.0, -3.0]"), ("workspace_max", "[3.0, 3.0, 3.0]"), ("joints.0.a_max", "200.0"),
    ("joints.3.j_max", "100000.0"), ("joints.0.tau_max", "200.0"), ("joints.4.tau_max", "28.0"),
    ("joints.0.v_max", "25.0"), ("joints.6.v_max", "8.0"), ("control_rate_hz", "100.0"),
])
def test_robot_config_limits_at_their_bounds_load(tmp_path, field, text):
    """The other side of the bounds above: a limit exactly at its bound is accepted."""
    path = tmp_path / "robot.toml"
    path.write_text(_robot_toml(field, "@@").replace('"@@"', text).replace("'@@'", text))
    config = load_robot_config(path)
    *parents, last = field.split(".")
    node = config
    for part in parents:
        node = node[int(part)] if part.isdigit() else getattr(node, part)
    assert getattr(node, last) == tomllib.loads(f"x = {text}")["x"]


@FUZZ
@given(data=BYTES)
def test_run_config_of_random_bytes_is_a_config_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("cfg") / "run.toml"
    path.write_bytes(data)
    try:
        load_config(path)
    except ConfigError as exc:
        assert str(path) in str(exc)


@FUZZ
@given(section=st.sampled_from(["opening", "geometry", "filter", "estimator", "perception", "estimator.screw"]),
       field=st.sampled_from(["timeout_s", "target_distance_m", "max_depth_m", "radius", "window", "box_threshold",
                              "voxel_m", "min_fitness", "camera_hz", "eps"]), value=NUMBERS)
def test_run_config_with_random_numbers_loads_finite_or_is_a_config_error(section, field, value):
    try:
        config = load_config(None, {f"{section}.{field}": value})
    except ConfigError:
        return
    assert all(math.isfinite(v) for v in _floats(config.model_dump()))


def _floats(data):
    if isinstance(data, float):
        yield data
    elif isinstance(data, dict):
        for v in data.values():
            yield from _floats(v)
    elif isinstance(data, (list, tuple)):
        for v in data:
            yield from _floats(v)


# --- calibration files -----------------------------------------------------------------------------------------


@FUZZ
@given(data=BYTES, yaml_header=st.booleans())
def test_calibration_file_of_random_bytes_is_a_calibration_error(tmp_path_factory, data, yaml_header):
    folder = tmp_path_factory.mktemp("cal")
    for path in (folder / "handeye.yaml", folder / "intrinsics_cam1.yaml"):
        path.write_bytes((b"%YAML:1.0\n---\n" if yaml_header else b"") + data)
    with pytest.raises(CalibrationError):
        load_hand_eye(folder / "handeye.yaml")
    with pytest.raises(CalibrationError):
        load_intrinsics_for("cam1", folder)


CALIBRATION_KEYS = ["format_version", "created", "camera_serial", "robot_id", "setup", "method", "tool_frame",
                    "T_camera", "T_board", "image_width", "image_height", "camera_matrix", "distortion",
                    "reprojection_px", "spread_mm", "spread_deg", "samples", "board_squares", "board_square_m",
                    "board_marker_m", "board_dictionary", "board_legacy", "rms_px", "views"]
STORAGE_VALUES = st.one_of(
    st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=12),
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**31, 2**31 - 1),
    st.tuples(st.integers(1, 5), st.integers(1, 5)).flatmap(
        lambda shape: st.lists(st.floats(-1e3, 1e3) | st.just(float("nan")), min_size=shape[0] * shape[1],
                               max_size=shape[0] * shape[1]).map(lambda v: np.array(v, float).reshape(shape))))


@FUZZ
@given(values=st.fixed_dictionaries({}, optional={k: STORAGE_VALUES for k in CALIBRATION_KEYS}))
def test_calibration_file_with_random_values_loads_or_is_a_calibration_error(tmp_path_factory, values):
    folder = tmp_path_factory.mktemp("cal")
    for path in (folder / "handeye.yaml", folder / "intrinsics_cam1.yaml"):
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        for key, value in {"format_version": 1, **values}.items():
            fs.write(key, value)
        fs.release()
    for load in (lambda: load_hand_eye(folder / "handeye.yaml"), lambda: load_intrinsics_for("cam1", folder)):
        try:
            record = load()
        except CalibrationError:
            continue
        assert np.isfinite(record.distortion).all()


# --- trajectory files (through the command line) ----------------------------------------------------------------


def _fit(capsys, path: Path) -> tuple[int, str]:
    code = main(["axis", "fit-trajectory", str(path), "--json"])
    return code, capsys.readouterr().err


@FUZZ
@given(data=BYTES)
def test_trajectory_file_of_random_bytes_is_one_line(tmp_path_factory, capsys, data):
    path = tmp_path_factory.mktemp("traj") / "handle.txt"
    path.write_bytes(data)
    code, err = _fit(capsys, path)
    assert code in (0, 1, 2) and "internal error" not in err and "Traceback" not in err


@FUZZ
@given(rows=st.lists(st.lists(REALS, min_size=3, max_size=8),
                     max_size=30))
def test_trajectory_file_with_random_numbers_is_an_axis_or_one_line(tmp_path_factory, capsys, rows):
    path = tmp_path_factory.mktemp("traj") / "handle.txt"
    path.write_text("\n".join(" ".join(str(v) for v in row) for row in rows) + "\n")
    code, err = _fit(capsys, path)
    assert code in (0, 1, 2) and "internal error" not in err and "Traceback" not in err


# --- the CAN frame parser --------------------------------------------------------------------------------------


@FUZZ
@given(data=st.binary(max_size=16), model=st.sampled_from(sorted(MODELS)), can_id=st.integers(1, 0x7FE))
def test_can_frame_parser_decodes_or_raises_frame_error(data, model, can_id):
    limits = MODELS[model]
    for parse in (lambda: unpack_feedback(data, limits), lambda: unpack_mit(data, limits),
                  lambda: unpack_param_reply(data), lambda: unpack_param_request(data)):
        try:
            parse()
        except FrameError:
            pass
    assert isinstance(is_param_reply(data, can_id), bool)
    if len(data) == 8:
        try:
            fb = unpack_feedback(data, limits)
        except FrameError:
            return
        assert all(math.isfinite(v) for v in (fb.q, fb.dq, fb.tau)) and abs(fb.q) <= limits.p_max + 1e-9
