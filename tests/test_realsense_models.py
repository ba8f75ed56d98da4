"""Every RealSense model of the model table: a software device with the model's stream profiles (resolutions,
formats, depth unit, intrinsics with the lens model), recorded to .db3 and converted with `deploy convert`, keeps its
depth unit (the D405's 0.1 mm), its colour intrinsics and lens coefficients and its minimum range; its colour comes
from the depth module where it has no colour camera; the distortion reaches the points depth becomes; the model
names on the command line; `cameras list`'s text."""

import json

import numpy as np
import pyrealsense2 as rs
import pytest
from cli_run import run
from realsense_models_devices import DEVICES, SERIAL, square_bounds, write_model_db3

from deploy.config import Config
from deploy.geometry.cloud import depth_to_points
from drivers.camera.frames_dir import FramesRecording
from drivers.camera.realsense import RealSenseCamera
from drivers.camera.realsense_config import RealSenseConfig
from drivers.camera.realsense_convert import convert_recording
from drivers.camera.realsense_models import model_named, model_of, models
from drivers.camera.realsense_playback import RealSenseReplayCamera
from drivers.camera.registry import open_camera
from drivers.errors import CameraError

MIN_RANGE_M = {"d415": 0.305, "d435": 0.195, "d455": 0.52, "d405": 0.07, "l515": 0.25}  # at each default resolution


class RecordedLink:
    """Where a RealSenseCamera's pipeline comes from, here a recording of a camera of `model` (in place of USB)."""

    def __init__(self, path, model):
        self.path, self.model, self.name = path, model, model.name.upper()

    def pipeline_config(self):
        config = rs.config()
        config.enable_device_from_file(str(self.path), repeat_playback=False)
        return config

    def prepare(self, device):
        assert device.get_info(rs.camera_info.name) == self.model.product

    def reset(self):
        raise CameraError(f"{self.name} (file) cannot be reset")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("models")
    return {name: write_model_db3(folder / f"{name}.db3", device) for name, device in DEVICES.items()}


def test_the_table_holds_every_model_with_its_source():
    assert list(models()) == ["d415", "d435", "d455", "d405", "l515"]
    for model in models().values():
        assert "Datasheet" in model.source and model.product.startswith("Intel RealSense")
        assert model.stream() == model.default  # the defaults are among the modes the model offers
        assert model.min_range_m(model.default.depth[1]) == pytest.approx(MIN_RANGE_M[model.name])
    assert model_named("d405").color_from_depth_module and not model_named("d455").color_from_depth_module
    assert model_of("Intel RealSense D435I") is model_named("d435") and model_of("Intel RealSense T265") is None


@pytest.mark.parametrize("name", list(DEVICES))
def test_each_model_converts_with_its_depth_unit_intrinsics_and_range(recordings, tmp_path, capsys, name):
    device = DEVICES[name]
    code, out, _ = run(capsys, "convert", recordings[name], "--out", tmp_path / "frames", "--json")
    assert code == 0, out
    summary = json.loads(out)
    assert summary["frames"] == 3 and summary["source_depth_scale"] == pytest.approx(device.depth_unit_m)
    meta = json.loads((tmp_path / "frames" / "meta.json").read_text())
    assert meta["depth_scale"] == pytest.approx(device.depth_unit_m, rel=1e-6)  # the D405's 0.1 mm kept
    assert meta["min_range_m"] == pytest.approx(MIN_RANGE_M[name])
    lens = device.color
    intrinsics = meta["intrinsics"]
    assert (intrinsics["width"], intrinsics["height"]) == (lens.width, lens.height)
    np.testing.assert_allclose([intrinsics[k] for k in ("fx", "fy", "cx", "cy")], [lens.fx, lens.fy, lens.cx, lens.cy],
                               rtol=1e-6)
    assert intrinsics["distortion"] == lens.model.name
    np.testing.assert_allclose(intrinsics["coeffs"], lens.coeffs, atol=1e-7)
    frame = FramesRecording(tmp_path / "frames").frame(0)
    units = np.unique(np.round(frame.depth_m[frame.depth_m > 0] / device.depth_unit_m)).tolist()
    assert units == [round(device.square_m / device.depth_unit_m), round(device.plane_m / device.depth_unit_m)]
    assert frame.color[0, 0, 0] == 0 and frame.color[5, 7, 1] == 7  # red = frame, green = column


def test_a_d405s_colour_comes_from_its_depth_module(recordings):
    camera = RealSenseReplayCamera(recordings["d405"])
    with camera:
        assert camera.min_range_m == pytest.approx(0.07) and camera.depth_scale == pytest.approx(1e-4)
        frame = camera.read()
    assert frame.depth_m[240, 424] == pytest.approx(0.2003, abs=1e-6)  # 2003 units of 0.1 mm, not 0.200


@pytest.mark.parametrize("name", ["d455", "d405", "l515"])
def test_the_colour_lens_distortion_reaches_the_points(recordings, tmp_path, name):
    device = DEVICES[name]
    convert_recording(recordings[name], tmp_path / "frames")
    frame = FramesRecording(tmp_path / "frames").frame(0)
    square = np.where(np.isclose(frame.depth_m, device.square_m, atol=1e-6), frame.depth_m, 0)
    lo, hi = square_bounds(device)
    pixel_m = device.square_m / device.color.fx
    with_lens = depth_to_points(square, frame.intrinsics.K, dist=frame.intrinsics.dist_coeffs)[:, :2]
    pinhole = depth_to_points(square, frame.intrinsics.K)[:, :2]
    offset = [device.baseline_m, 0.0]  # the colour camera's frame -> the depth camera's
    xy = with_lens - offset
    assert np.all(xy >= lo - pixel_m) and np.all(xy <= hi + pixel_m)  # the square where the depth camera saw it
    np.testing.assert_allclose([xy.min(axis=0), xy.max(axis=0)], [lo, hi], atol=2 * pixel_m)  # all of it
    xy = pinhole - offset
    assert np.any(xy < lo - pixel_m) or np.any(xy > hi + pixel_m)  # a pinhole K alone puts it pixels away


def test_the_live_camera_reads_each_model(recordings):
    """The live camera's pipeline (`RealSenseStream`) on each model's recording: the D405's colour from its depth
    module, and depth aligned through the colour lens (where librealsense's x86 `rs.align` ignores it)."""
    for name, path in recordings.items():
        link = RecordedLink(path, model_named(name))
        with RealSenseCamera(RealSenseConfig(warmup_frames=0, frame_timeout_s=5.0), link) as camera:
            frame = camera.read()
            assert camera.min_range_m == pytest.approx(MIN_RANGE_M[name])
            assert camera.intrinsics.distortion == DEVICES[name].color.model.name
        assert frame.depth_m.shape == (DEVICES[name].color.height, DEVICES[name].color.width)
        square = np.isclose(frame.depth_m, DEVICES[name].square_m, atol=1e-5)
        assert square.sum() > 1000, name


def test_perception_drops_depth_nearer_than_the_cameras_minimum_range(tmp_path):
    """The episode's observer takes its near limit from the camera (here a recording whose meta.json keeps a D455's
    0.52 m), unless the config sets one; a camera that does not say keeps 0.1 m."""
    from deploy.control.observer import Observer
    from drivers.camera.base import Frame, Intrinsics
    from drivers.camera.frames_dir import FramesReplayCamera, FramesWriter

    intrinsics = Intrinsics(64, 48, 50.0, 50.0, 31.5, 23.5)
    depth = np.full((48, 64), 0.45, np.float32)
    depth[:, 32:] = 0.8  # half the image nearer than a D455 measures
    frame = Frame(0, 0.0, np.zeros((48, 64, 3), np.uint8), depth, intrinsics)
    for name, min_range_m in (("d455", 0.52), ("unknown", None)):
        with FramesWriter(tmp_path / name, intrinsics, min_range_m=min_range_m) as writer:
            writer.write(frame)
    d455, unknown = FramesReplayCamera(tmp_path / "d455"), FramesReplayCamera(tmp_path / "unknown")
    assert d455.min_range_m == 0.52 and unknown.min_range_m is None
    mask = np.ones((48, 64), bool)

    def points(config, camera):
        return len(Observer(camera, None, None, config, None).points(frame, mask))

    everything = points(Config(), unknown)  # 0.1 m
    assert everything == 48 * 64 // 4  # the pipeline's decimation 2
    assert points(Config(), d455) == everything // 2
    assert points(Config().replace(geometry={"min_depth_m": 0.2}), d455) == everything  # the user's own


@pytest.mark.parametrize("name", list(DEVICES))
def test_each_model_name_sets_its_defaults(name):
    model = model_named(name)
    camera = open_camera(name)
    assert camera.config.model == name and camera.config.stream(model) == model.default
    with pytest.raises(CameraError, match=f"{name.upper()}: colour resolution 123x45 is not supported"):
        open_camera(name, width=123, height=45)


def test_model_names_on_the_command_line(capsys, tmp_path):
    code, _, err = run(capsys, "cameras", "snapshot", "--camera", "d435", "--out", tmp_path / "snap")
    assert code == 2 and "no D435 is connected" not in err and "no RealSense camera is connected" in err
    code, _, err = run(capsys, "cameras", "snapshot", "--camera", "d999", "--out", tmp_path / "snap")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "unknown camera 'd999': choose one of realsense[:SERIAL], d415[:SERIAL], d435[:SERIAL], d455[:SERIAL], " \
           "d405[:SERIAL], l515[:SERIAL]" in " ".join(err.split())


def test_a_serial_of_another_model_is_refused():
    from drivers.camera.realsense_device import UsbLink

    link = UsbLink(RealSenseConfig(model="d435", serial=SERIAL))
    with pytest.raises(CameraError, match=f"camera {SERIAL} is an Intel RealSense D415, not a D435: use --camera "
                                          f"d415:{SERIAL}"):
        link._choose({SERIAL: "Intel RealSense D415"})
    with pytest.raises(CameraError, match=r"no D435 is connected \(connected: 1 \(Intel RealSense D415\)\)"):
        UsbLink(RealSenseConfig(model="d435"))._choose({"1": "Intel RealSense D415"})
    any_model = UsbLink(RealSenseConfig(model=None))
    assert any_model._choose({"1": "Intel RealSense D455"}) == "Intel RealSense D455" and any_model.serial == "1"


def test_cameras_list_text(recordings):
    """`cameras list` on each model's device as its recording stands it (librealsense does not enumerate software
    devices: the description and its text are what is checked)."""
    from deploy.commands.cameras import camera_lines
    from drivers.camera.realsense_device import describe_device

    for name, path in recordings.items():
        device = rs.context().load_device(str(path))
        described = describe_device(device)
        assert described["model"] == name and described["serial"] == SERIAL
        assert described["depth_scale"] == pytest.approx(DEVICES[name].depth_unit_m)
        assert described["color_sensor"] == DEVICES[name].color_sensor
        text = camera_lines(described)
        assert max(map(len, text)) <= 80, text
        joined = "\n".join(text)
        assert f"{name.upper()} {DEVICES[name].product}" in joined and f"serial {SERIAL}, firmware 5.16.0.1" in joined
        lens = DEVICES[name].color
        assert f"colour {lens.width}x{lens.height} from the {DEVICES[name].color_sensor}: fx {lens.fx:.2f}" in joined
        assert f"  {lens.model.name}: k1 {lens.coeffs[0]:.4g} k2" in joined
        assert described["min_range_m"] == pytest.approx(MIN_RANGE_M[name])
        assert f"minimum range {described['min_range_m']:.2f} m" in joined
