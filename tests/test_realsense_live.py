"""The live RealSense camera's logic (background latest-frame reader, warm-up, timeout -> retry -> hardware reset ->
reconnect -> one clear error, recording kept when the camera vanishes) on real librealsense pipelines fed from
a recorded .db3 instead of USB; config validation; device description; no-camera errors."""

import threading
import time

import pyrealsense2 as rs
import pytest
from realsense_recordings import SERIAL, scene, write_db3

from drivers.camera.frames_dir import FramesRecording
from drivers.camera.realsense import RealSenseCamera
from drivers.camera.realsense_config import FilterConfig, RealSenseConfig
from drivers.camera.realsense_device import UsbLink, describe_device, list_devices
from drivers.camera.realsense_models import model_named
from drivers.camera.realsense_reader import LatestFrameReader
from drivers.camera.record import record
from drivers.camera.registry import open_camera
from drivers.errors import CameraError, RecordingError

N = 10


class FileLink:
    """A D415 link whose "device" is a .db3 file: reset reopens it, and fails once the file is gone
    (the camera was unplugged)."""

    name = "D415 (file)"

    def __init__(self, path):
        self.path = path
        self.prepared = 0
        self.model = model_named("d415")

    def pipeline_config(self):
        config = rs.config()
        config.enable_device_from_file(str(self.path), repeat_playback=False)
        return config

    def prepare(self, device):
        assert device.get_info(rs.camera_info.serial_number) == SERIAL
        device.as_playback().set_real_time(False)  # every frame delivered, however loaded the machine
        self.prepared += 1

    def reset(self):
        if not self.path.exists():
            raise CameraError(f"{self.name} did not come back after a hardware reset")


@pytest.fixture
def db3(tmp_path):
    return write_db3(tmp_path / "live.db3", scene(N))


def camera(path, **options):
    defaults = {"warmup_frames": 0, "frame_timeout_s": 0.2, "retries": 1, "filters": FilterConfig.none()}
    return RealSenseCamera(RealSenseConfig(**{**defaults, **options}), FileLink(path))


def wait_until_drained(cam, timeout_s: float = 20.0, quiet_s: float = float("inf")) -> None:
    """Until the background reader has received the recording's last frame, or no new frame for `quiet_s`."""
    deadline, seen, since = time.monotonic() + timeout_s, None, time.monotonic()
    while time.monotonic() < deadline:
        latest = cam._reader.latest
        index = None if latest is None else latest.index
        if index == N - 1 or (index is not None and index == seen and time.monotonic() - since > quiet_s):
            return
        if index != seen:
            seen, since = index, time.monotonic()
        time.sleep(0.02)


def test_reader_serves_the_latest_frame(db3):
    with camera(db3) as cam:
        assert cam.intrinsics.fx == 50.0 and cam.depth_scale == pytest.approx(1e-4)
        assert cam.link.prepared == 1
        wait_until_drained(cam, quiet_s=2.0)  # file playback on a loaded machine can stall for seconds
        newest = cam._reader.latest.index  # a stalled playback may still deliver a later frame
        frame = cam.read()
        assert frame.index >= newest and frame.t == pytest.approx(frame.index / 30, abs=1e-6)
        assert frame.color[0, 0, 0] == frame.index and frame.depth_m[23, 29] == pytest.approx(0.8, abs=1e-4)


def test_warm_up_drops_frames(db3):
    with camera(db3, warmup_frames=4, frame_timeout_s=5.0) as cam:  # a loaded machine plays the file back slowly
        assert cam.read().index >= 4


def test_timeout_retries_then_resets_and_reconnects(db3):
    with camera(db3) as cam:
        wait_until_drained(cam)
        last = cam.read()
        frame = cam.read()  # the file has ended: 2 timeouts, a reset, a new pipeline from the start
        assert cam.resets == 1 and cam.link.prepared == 2
        assert frame.index > last.index and frame.t > last.t  # the timeline continues across the reconnect


def test_unplugged_camera_is_one_clear_error_and_released(db3):
    cam = camera(db3)
    with cam:
        wait_until_drained(cam)
        cam.read()
        db3.unlink()  # "unplugged": the reset cannot bring it back
        with pytest.raises(CameraError, match=r"D415 \(file\) stopped delivering frames .*did not come back"):
            cam.read()
        assert cam._stream is None and cam._reader is None  # released


def test_recording_stops_safely_and_keeps_frames_when_the_camera_vanishes(db3, tmp_path):
    cam = camera(db3)
    kept = []

    def unplug_after_three(frame):
        kept.append(frame.index)
        if len(kept) == 3 and db3.exists():
            db3.unlink()

    with pytest.raises(CameraError, match=r"recording stopped: the \d+ frames recorded so far are kept"):
        record(cam, tmp_path / "rec", seconds=100.0, progress=unplug_after_three)
    rec = FramesRecording(tmp_path / "rec")
    assert len(rec) == len(kept) >= 3
    times = [rec.frame(i).t for i in range(len(rec))]
    assert times == sorted(set(times))


def test_reader_finishes_only_the_frames_read():
    items, finished, polled = iter(range(50)), [], threading.Event()

    def poll(timeout_s):
        item = next(items, None)
        if item is None:  # all 50 polled (and the last kept)
            polled.set()
            time.sleep(timeout_s)
        return item

    reader = LatestFrameReader(poll, lambda item: finished.append(item) or item, poll_timeout_s=0.01)
    assert polled.wait(30)
    assert reader.read(1.0) == 49 and finished == [49]  # the newest, and only it, made a frame
    reader.stop()


def test_reader_hands_over_errors_and_timeouts():
    frames = iter([None, None])

    def poll(timeout_s):
        value = next(frames, "gone")
        if value == "gone":
            raise RuntimeError("Frame didn't arrive within 5000")
        time.sleep(timeout_s)
        return value

    reader = LatestFrameReader(poll, poll_timeout_s=0.01)
    with pytest.raises(RuntimeError, match="didn't arrive"):
        reader.read(1.0)
    reader.stop()
    quiet = LatestFrameReader(lambda t: time.sleep(t), poll_timeout_s=0.01)
    assert quiet.read(0.05) is None
    quiet.stop()


@pytest.mark.parametrize("options, message", [
    ({"width": 1000, "height": 480}, "D415: colour resolution 1000x480 is not supported; choose one of 1920x1080, "),
    ({"width": 1280, "height": 720, "fps": 60}, "60 fps is not offered for colour at 1280x720; choose one of 6, 15, "),
    ({"width": 1000}, "D415: colour resolution 1000x480 is not supported"),
    ({"visual_preset": "sharp"}, "unknown visual preset 'sharp'"),
    ({"color_exposure": -1.0}, "color_exposure must be a positive number"),
    ({"decimation": 9}, "decimation must be 1"),
    ({"hole_filling": "magic"}, "unknown hole_filling 'magic'"),
    ({"zoom": 2}, "unknown option.*zoom.*valid: .*width"),
])
def test_config_errors_name_the_setting(options, message):
    with pytest.raises(CameraError, match=message):
        open_camera("d415", **options)


def test_config_from_options():
    config = RealSenseConfig.from_options("123", width=1280, height=720, visual_preset="high_accuracy",
                                          temporal=True)
    assert config.serial == "123" and config.filters.temporal and config.filters.spatial
    assert open_camera("d415:123").link.serial == "123" and open_camera("d435:123").config.model == "d435"


def test_no_camera_connected():
    assert list_devices() == []  # no camera on this machine: an empty list, not an error
    with pytest.raises(CameraError, match="no RealSense camera is connected"):
        UsbLink(RealSenseConfig(serial="999")).pipeline_config()
    with pytest.raises(CameraError, match="no RealSense camera is connected"), open_camera("d415:999"):
        pass


def test_describe_device():
    device = rs.software_device()
    for info, value in ((rs.camera_info.serial_number, "42"), (rs.camera_info.name, "Intel RealSense D415"),
                        (rs.camera_info.firmware_version, "5.16.0.1"), (rs.camera_info.usb_type_descriptor, "3.2")):
        device.register_info(info, value)
    sensor = device.add_sensor("Stereo Module")
    stream = rs.video_stream()
    stream.type, stream.uid, stream.width, stream.height, stream.fps = rs.stream.depth, 0, 640, 480, 30
    stream.bpp, stream.fmt, stream.intrinsics = 2, rs.format.z16, rs.intrinsics()
    sensor.add_video_stream(stream)
    assert describe_device(device) == {
        "serial": "42", "name": "Intel RealSense D415", "model": "d415", "firmware": "5.16.0.1", "usb_type": "3.2",
        "color_sensor": None, "depth_scale": None, "intrinsics": None, "min_range_m": pytest.approx(0.305),
        "stream": {"color": "640x480", "depth": "640x480", "fps": 30}, "profiles": ["Depth 640x480 Z16 @30"]}


def test_unknown_camera_spec():
    with pytest.raises(CameraError, match=r"unknown camera 'kinect': choose one of realsense\[:SERIAL\], "
                                          r"d415\[:SERIAL\], d435\[:SERIAL\], d455\[:SERIAL\], d405\[:SERIAL\], "
                                          r"l515\[:SERIAL\], replay:PATH, sim$"):
        open_camera("kinect")
    with pytest.raises(CameraError, match="camera 'replay' needs an argument: write replay:PATH"):
        open_camera("replay:")
    with pytest.raises(RecordingError, match="not found"):
        open_camera("replay:/nonexistent/dir")
