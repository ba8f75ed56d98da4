"""`deploy axis estimate`: run the axis pipeline over a frames-directory recording with stored masks."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deploy.axis_pipeline import AxisPipeline, StepResult
from deploy.config import Config
from deploy.errors import RecordingError
from deploy.geometry.types import Axis, NoAxis
from drivers.camera.frames_dir import FramesRecording

log = logging.getLogger(__name__)
APPROACH = ("the gripper does not hold the handle yet (frames.jsonl grasped false): the approach is left out, "
            "nothing has moved the part")


def estimate_recording(path: Path, config: Config, progress: Callable[[float, float], None] | None = None,
                       viewer: Any = None) -> dict:
    """The frames through the pipeline, in order; returns the last axis a frame gave (`from_frame`: that frame;
    with none, the last frame's reason), the estimate per step and the filter used (`filter`: radius_m, eps).
    RecordingError for a recording without frames or with a frame without its mask. A frame marked `first` (a run
    that looked again from the start) starts the pipeline over, as the run did: its body box is fixed there.

    The gripper's path (frames.jsonl `ee_pose`, e.g. from `deploy record --arm`) goes in with the frames where
    recorded (`gripper_path`: the estimator used it; `gripper_frames`: the frames whose pose went in). A recording
    that says when the gripper held the handle (`grasped` on any frame: `deploy sim record`, run folders) gives it
    only on the frames marked true, and leaves the approach out (the frames before the first one marked true, but
    the one that fixes the body box), as a run does: nothing held the part, so nothing moved it, and what the
    estimator made of those frames is noise (a bar handle's roll about itself, which registration cannot see,
    reads as a turn). Their steps give the reason `APPROACH`; each step's `grasped` is its frame's mark (null
    without one).

    The body box's front is its face toward the robot's base when an arm made the recording (`ee_pose`) and it
    has the camera's pose, else its face toward the camera (a camera beside the part may see a side best).

    Depth nearer than the recording camera's minimum range (meta.json `min_range_m`) is left out, unless
    `geometry.min_depth_m` says otherwise. Axes are in the base frame when the recording has `T_base_camera`, else
    in the camera frame. progress(done, total) follows the frames; `viewer` (deploy.report.viewer.RerunViewer) is
    shown every frame, its mask and the axis estimated at it, and is closed at the end. `deploy --verbose` logs the
    config used and every frame's estimate.
    """
    recording = _masked_recording(path)
    config = config.for_range(recording.min_range_m)
    e = config.estimator
    log.info("estimate config: filter %s (%s); estimator %s, joint %s, window %d; %d frames in %s",
             config.filter.profile, config.filter.resolve(), e.name, e.joint, e.window, len(recording), path)
    toward = _robot_base(recording)
    pipe = AxisPipeline(config, toward=toward)
    steps, final, last, gripper_frames = [], None, None, 0
    approach = recording.marks_grasp  # until the first frame marked grasped
    try:
        for i in range(len(recording)):
            frame = recording.frame(i)
            pose = recording.held_pose(i)
            gripper_frames += pose is not None
            approach = approach and recording.records[i].get("grasped") is not True
            if i > 0 and recording.records[i].get("first"):
                pipe = AxisPipeline(config, toward=toward)
            if approach and pipe.body_box is not None:
                step = StepResult(frame.index, frame.t, NoAxis(APPROACH), 0, 0)
            else:
                step = pipe.update_frame(frame, frame.mask, pose)
            last = frame.index, step.result
            log.info("frame %d (t %.2f s): %s", frame.index, frame.t, _estimate_text(step.result))
            if isinstance(step.result, Axis):
                final = last
            steps.append({**_entry(frame.index, step), "grasped": recording.records[i].get("grasped")})
            if viewer is not None:
                viewer.frame(frame.t, frame, frame.mask, _pose(recording.records[i]))
                if isinstance(step.result, Axis):
                    viewer.axis(frame.t, step.result, None, "vision", i)
            if progress is not None:
                progress(i + 1, len(recording))
    finally:
        if viewer is not None:
            viewer.close()
    out = {
        "estimator": config.estimator.name, "joint_type": None, "origin": None, "direction": None,
        "radius_m": None, "residual_m": None, "n_samples": len(recording),
        "frame": "base" if recording.T_base_camera is not None else "camera",
        "gripper_path": pipe.estimator.use_gripper and gripper_frames > 0,
        "gripper_frames": gripper_frames if pipe.estimator.use_gripper else 0,
        "filter": config.filter.used(), "steps": steps,
    }
    out["from_frame"], result = final or last
    if isinstance(result, Axis):
        out.update(result.to_dict())
    else:
        out["reason"] = result.reason
    return out


def _robot_base(recording: FramesRecording) -> np.ndarray | None:
    """The robot's base (the base frame's origin) when an arm made the recording (its poses recorded) and the
    camera's pose is known (the points are then in the base frame); else None. The part a robot opens faces it."""
    if recording.T_base_camera is None or not any(r.get("ee_pose") is not None for r in recording.records):
        return None
    return np.zeros(3)


def _estimate_text(result: Axis | NoAxis) -> str:
    """One estimate for the log: joint type, direction, origin (m), confidence and sigma; or why there is none."""
    if isinstance(result, NoAxis):
        return f"no axis ({result.reason})"
    d, o = np.round(result.direction, 3).tolist(), np.round(result.origin, 3).tolist()
    sigma = "" if result.direction_sigma_deg is None else f", direction sigma {result.direction_sigma_deg:.2f} deg"
    return f"{result.joint_type.value} axis, direction {d}, origin {o} m, confidence {result.confidence:.2f}{sigma}"


def _pose(record: dict) -> np.ndarray | None:
    pose = record.get("ee_pose")
    return None if pose is None else np.asarray(pose)


def _masked_recording(path: Path) -> FramesRecording:
    """The recording at `path`; RecordingError unless it has frames and every frame has its mask."""
    recording = FramesRecording(path)
    if len(recording) == 0:
        raise RecordingError(f"recording {path} has no frames (frames.jsonl is missing or empty): record again "
                             "(`deploy record`, `deploy sim record`)")
    unmasked = recording.unmasked
    if len(unmasked) == len(recording):
        raise RecordingError(
            f"recording {path} has no masks (no mask/ PNGs): the axis needs the object's mask per frame; "
            "record in simulation (`deploy sim record`) or add masks with `deploy track` first"
        )
    if unmasked:
        raise RecordingError(
            f"recording {path}: frame {unmasked[0]} has no mask (mask/{unmasked[0]:06d}.png is missing; "
            f"{len(unmasked)} of {len(recording)} frames lack one): re-run `deploy track {path} --out NEW` "
            "to mask every frame"
        )
    return recording


def _entry(index: int, step) -> dict:
    """One frame's estimate for the JSON, with its confidence and direction sigma (deg) to tell a firm one from
    an early guess."""
    kept = ("joint_type", "origin", "direction", "confidence", "direction_sigma_deg")
    entry = {"frame": index, **dict.fromkeys(kept), "moving_points": step.moving_points}
    if isinstance(step.result, Axis):
        entry.update({k: v for k, v in step.result.to_dict().items() if k in kept})
    else:
        entry["reason"] = step.result.reason
    return entry
