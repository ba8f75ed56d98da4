"""RealSense recordings to frames directories: the SDK's `.bag` / `.db3` (librealsense playback) and ROS 2 bags
of realsense-ros topics (`.db3`, `.mcap` or the bag folder, read with rosbags); depth aligned to colour and
re-quantised to the directory's scale."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from drivers.camera.base import Camera, Frame
from drivers.camera.record import record
from drivers.errors import RecordingError

ROS2_SUFFIXES = (".mcap",)


def recording_kind(src: Path) -> str:
    """"realsense" (an SDK .bag or .db3), "ros2" (a realsense-ros bag: .db3, .mcap or a folder holding
    metadata.yaml) or "frames" (a frames directory or anything else)."""
    suffix = src.suffix.lower()
    if suffix == ".bag":
        return "realsense"
    if suffix == ".db3":
        from drivers.camera.ros2_bag import is_sdk_recording

        return "realsense" if not src.is_file() or is_sdk_recording(src) else "ros2"
    if suffix in ROS2_SUFFIXES or (src.is_dir() and (src / "metadata.yaml").is_file()):
        return "ros2"
    return "frames"


def open_recording(src: Path) -> Camera:
    """The camera that plays the RealSense or ROS 2 recording `src` once, not yet connected."""
    kind = recording_kind(src)
    if kind == "realsense":
        from drivers.camera.realsense_playback import RealSenseReplayCamera

        return RealSenseReplayCamera(src)
    if kind == "ros2":
        from drivers.camera.ros2_bag import Ros2BagCamera

        return Ros2BagCamera(src)
    raise RecordingError(f"cannot convert {src}: expected a RealSense .bag or .db3 recording, or a ROS 2 bag of "
                         "realsense-ros topics (.db3, .mcap or its folder)")


def convert_recording(
    src: str | Path, out: str | Path, depth_scale: float | None = None,
    progress: Callable[[Frame], None] | None = None
) -> dict:
    """Every frame of `src`, depth aligned to colour, raw (no post-processing), with the colour stream's
    intrinsics (lens model and coefficients included), written to the frames directory `out` in units of
    `depth_scale` m (None: the source's own unit, at most 1 mm, so a D405's 0.1 mm steps are kept). Depth beyond the
    16-bit range of `depth_scale` is stored as 0, no depth (`depth_units`). Returns {"out", "frames", "seconds",
    "source", "depth_scale", "source_depth_scale", "depth_out_of_range_px", "source_frames", "unpaired_frames"}
    (source: "realsense" or "ros2"; depth_scale: the directory's unit; source_depth_scale: metres per unit of the
    source's depth; depth_out_of_range_px: the depth pixels stored as 0 for being beyond the range; source_frames:
    {"depth", "color"} frames the recording's index lists and unpaired_frames: {"depth", "color"} frames without a
    partner in the other stream, both for a RealSense recording, else None). RecordingError when librealsense played
    fewer frames than the recording holds (the frames written stay in `out`)."""
    src = Path(src)
    camera = open_recording(src)
    camera.connect()
    source_depth_scale = camera.depth_scale
    summary = record(camera, out, depth_scale=depth_scale, progress=progress,  # disconnects the camera
                     source=f"replay:{src}")
    lost = camera.lost_frames() if hasattr(camera, "lost_frames") else None
    if lost:
        raise RecordingError(f"converted only {summary['frames']} frames of {src}: {lost}; convert it again "
                             f"(--overwrite replaces {out}), and if frames stay missing the file holds unreadable "
                             "frames: record it again")
    return {**summary, "source": recording_kind(src), "source_depth_scale": source_depth_scale,
            "source_frames": getattr(camera, "recorded", None), "unpaired_frames": getattr(camera, "unpaired", None)}
