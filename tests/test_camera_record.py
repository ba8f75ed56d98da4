"""Recording any camera to a frames directory: stop conditions, Ctrl-C keeps a readable recording, and the
factory's frames-directory replay options."""

import numpy as np
import pytest

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesReplayCamera
from drivers.camera.record import record
from drivers.camera.registry import open_camera
from drivers.errors import CameraError, RecordingError

INTR = Intrinsics(16, 12, 20.0, 20.0, 7.5, 5.5)


class CountingCamera(Camera):
    """Frame k: colour k everywhere, depth 1 + k mm, at t = k / 10 s."""

    def __init__(self):
        self.k = 0

    @property
    def intrinsics(self):
        return INTR

    def read(self, timeout_s=2.0):
        frame = Frame(self.k, self.k / 10, np.full((12, 16, 3), self.k, np.uint8),
                      np.full((12, 16), 1.0 + self.k / 1000, np.float32), INTR)
        self.k += 1
        return frame


def test_stops_after_frames_or_seconds(tmp_path):
    assert record(CountingCamera(), tmp_path / "a", frames=5)["frames"] == 5
    summary = record(CountingCamera(), tmp_path / "b", seconds=0.35)
    assert summary["frames"] == 4 and summary["seconds"] == pytest.approx(0.4)  # t = 0 .. 0.3 kept
    rec = FramesRecording(tmp_path / "b")
    assert [rec.frame(i).t for i in range(4)] == pytest.approx([0, 0.1, 0.2, 0.3])
    assert rec.frame(3).depth_m[0, 0] == pytest.approx(1.003)


def test_interrupted_recording_is_readable_to_its_last_frame(tmp_path):
    def interrupt(frame):
        if frame.index == 6:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        record(CountingCamera(), tmp_path / "rec", seconds=100, progress=interrupt)
    camera = FramesReplayCamera(tmp_path / "rec")
    frames = []
    with camera, pytest.raises(RecordingError, match="end of recording"):
        while True:
            frames.append(camera.read())
    assert [f.color[0, 0, 0] for f in frames] == list(range(7))


def test_bad_lengths(tmp_path):
    with pytest.raises(RecordingError, match="must be positive"):
        record(CountingCamera(), tmp_path / "x", frames=0)


def test_factory_replay_options(tmp_path):
    record(CountingCamera(), tmp_path / "rec", frames=3)
    with open_camera(f"replay:{tmp_path / 'rec'}", loop=True) as camera:
        indices = [camera.read().index for _ in range(5)]
    assert indices == [0, 1, 2, 3, 4]  # looped, indices keep increasing
    with pytest.raises(CameraError, match="unknown option.*fps.*valid: loop, realtime"):
        open_camera(f"replay:{tmp_path / 'rec'}", fps=30)
