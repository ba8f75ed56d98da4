"""A frame written by `FramesWriter.write` is on disk when `write` returns: another process reads it while the writer
is still open, and again after the writer was killed (SIGKILL, no close); and the writer fsyncs each frame's PNGs
and their directories before its frames.jsonl line, which it flushes and fsyncs last (observed on the real os.fsync)."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesRecording, FramesWriter

ROOT = Path(__file__).resolve().parents[1]
INTRINSICS = Intrinsics(64, 48, 60.0, 60.0, 32.0, 24.0)
N_FRAMES = 3

WRITER = f"""
import sys
import numpy as np
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.frames_dir import FramesWriter

intrinsics = Intrinsics(64, 48, 60.0, 60.0, 32.0, 24.0)
writer = FramesWriter(sys.argv[1], intrinsics)
for i in range({N_FRAMES}):
    color = np.full((48, 64, 3), 40 * i + 10, np.uint8)
    depth = np.full((48, 64), 0.5 + 0.1 * i, np.float32)
    mask = np.zeros((48, 64), bool)
    mask[: 10 + 5 * i] = True
    writer.write(Frame(index=i, t=0.1 * i, color=color, depth_m=depth, intrinsics=intrinsics, mask=mask),
                 joint_positions=[float(i)] * 7)
    print(f"written {{i}}", flush=True)
    sys.stdin.readline()  # the reader's turn; the writer stays open
"""


def _assert_frames(path: Path, n: int) -> None:
    """The recording at `path` holds exactly frames 0 .. n-1 as the writer wrote them."""
    recording = FramesRecording(path)
    assert len(recording) == n
    for i in range(n):
        frame = recording.frame(i)
        assert frame.index == i and frame.t == pytest.approx(0.1 * i)
        assert np.all(frame.color == 40 * i + 10)
        np.testing.assert_allclose(frame.depth_m, 0.5 + 0.1 * i, atol=1e-3)
        assert frame.mask.sum() == (10 + 5 * i) * 64
        assert recording.records[i]["joint_positions"] == [float(i)] * 7


def test_each_frame_is_readable_by_another_process_once_write_returns_and_after_the_writer_is_killed(tmp_path):
    path = tmp_path / "rec"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, cwd=ROOT,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        for i in range(N_FRAMES):
            assert writer.stdout.readline().strip() == f"written {i}"
            _assert_frames(path, i + 1)  # read by this process while the writer is open
            if i < N_FRAMES - 1:
                writer.stdin.write("next\n")
                writer.stdin.flush()
        writer.send_signal(signal.SIGKILL)  # killed with the recording open: nothing closes or flushes it
        assert writer.wait(timeout=10) == -signal.SIGKILL
    finally:
        if writer.poll() is None:
            writer.kill()
            writer.wait()
    _assert_frames(path, N_FRAMES)


def _frame(i: int, mask: bool = True) -> Frame:
    m = np.zeros((48, 64), bool) if mask else None
    return Frame(index=i, t=0.1 * i, color=np.zeros((48, 64, 3), np.uint8), depth_m=np.ones((48, 64), np.float32),
                 intrinsics=INTRINSICS, mask=m)


@pytest.mark.parametrize("mask", [True, False])
def test_a_frames_line_is_flushed_and_fsynced_after_its_images_and_their_directories(tmp_path, monkeypatch, mask):
    fsync = os.fsync
    synced: list[tuple[str, int]] = []  # (path relative to the recording, its size when fsynced)

    def observed_fsync(fd: int) -> None:
        fsync(fd)
        name = os.path.relpath(os.readlink(f"/proc/self/fd/{fd}"), tmp_path / "rec")
        synced.append((name, os.fstat(fd).st_size))

    monkeypatch.setattr(os, "fsync", observed_fsync)
    writer = FramesWriter(tmp_path / "rec", INTRINSICS)
    assert {name for name, _ in synced} >= {"meta.json", ".", ".."}  # the recording's entries reach the disk
    lines = 0
    for i in range(2):
        synced.clear()
        writer.write(_frame(i, mask), joint_positions=[0.0] * 7)
        lines += len((tmp_path / "rec" / "frames.jsonl").read_text().splitlines()[-1]) + 1
        names = [name for name, _ in synced]
        images = {f"{sub}/{i:06d}.png" for sub in ("color", "depth", "mask")[: 3 if mask else 2]}
        directories = {"color", "depth", "mask"} if mask else {"color", "depth"}
        assert names[-1] == "frames.jsonl" and names.count("frames.jsonl") == 1  # the line last, once
        assert set(names[:-1]) - {"."} == images | directories  # before it: every image and its directory
        assert all(names.index(image) < names.index(image.split("/")[0]) for image in images)
        assert synced[-1][1] == lines  # the line was flushed before the fsync: all of it is in the file
    writer.close()
