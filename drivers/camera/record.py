"""Record any camera to a frames directory, one flushed frame at a time; a failing camera keeps what was recorded."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from drivers.camera.base import Camera, Frame
from drivers.camera.frames_dir import DEPTH_SCALE, FramesWriter
from drivers.errors import CameraError, RecordingError

ArmReading = Callable[[], tuple[np.ndarray, np.ndarray]]  # () -> (joint positions rad/m, tool pose 4x4 base frame)


def record(
    camera: Camera,
    out: str | Path,
    frames: int | None = None,
    seconds: float | None = None,
    depth_scale: float | None = None,
    progress: Callable[[Frame], None] | None = None,
    source: str | None = None,
    simulated: bool = False,
    arm: ArmReading | None = None,
    robot: str | None = None,
) -> dict:
    """Read `camera` (connected here) into the frames directory `out` until `frames` frames or `seconds`
    of camera time (whichever comes first), or until a replay ends (the only stop if neither is set).

    depth_scale: metres per unit of the stored depth; None: the camera's own unit, at most 1 mm (a D405's 0.1 mm
    steps are kept; a camera giving metres as floats is stored in mm).
    source: the camera's spec and simulated: whether it renders a simulation (both go to meta.json, with the
    camera's minimum range); arm():
    the arm's joint positions and tool pose, read right after each frame and stored with it (`robot`: its config,
    named in meta.json). A frame's pose
    (a camera on the arm moves) is stored where it differs from the first frame's (FramesWriter).
    A camera failure (e.g. unplugged) stops the recording and raises CameraError saying how many frames
    were kept; they stay readable. Returns {"out", "frames", "seconds", "arm", "depth_scale",
    "depth_out_of_range_px"} (depth pixels stored as no depth: beyond what 16 bits of `depth_scale` hold).
    """
    if (frames is not None and frames <= 0) or (seconds is not None and seconds <= 0):
        raise RecordingError(f"frames and seconds must be positive, got frames={frames} seconds={seconds}")
    count, t0, t = 0, None, 0.0
    with camera:
        first = camera.read()
        depth_scale = min(camera.depth_scale, DEPTH_SCALE) if depth_scale is None else depth_scale
        with FramesWriter(out, camera.intrinsics, depth_scale, first.T_base_camera, source, simulated,
                          min_range_m=camera.min_range_m, robot=robot) as writer:
            frame = first
            while True:
                t0 = frame.t if t0 is None else t0
                t = frame.t - t0
                if seconds is not None and t >= seconds:
                    break
                q, tool = arm() if arm is not None else (None, None)
                writer.write(frame, joint_positions=q, ee_pose=tool)
                count += 1
                if progress is not None:
                    progress(frame)
                if frames is not None and count >= frames:
                    break
                try:
                    frame = camera.read()
                except RecordingError:  # a replay ended
                    break
                except CameraError as exc:
                    raise CameraError(f"{exc}; recording stopped: the {count} frames recorded so far are kept "
                                      f"in {out}") from None
    return {"out": str(out), "frames": count, "seconds": t, "arm": arm is not None, "depth_scale": depth_scale,
            "depth_out_of_range_px": writer.depth_out_of_range_px}
