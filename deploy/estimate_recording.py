"""`deploy axis estimate`: run the axis pipeline over a frames-directory recording with stored masks."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from deploy.axis_pipeline import AxisPipeline
from deploy.config import Config
from deploy.errors import RecordingError
from deploy.geometry.types import Axis
from drivers.camera.frames_dir import FramesRecording


def estimate_recording(path: Path, config: Config) -> dict:
    """Every frame through the pipeline, in order; returns the final axis and the estimate per step.

    Axes are in the base frame when the recording has `T_base_camera`, else in the camera frame.
    """
    recording = FramesRecording(path)
    if not recording.has_masks:
        raise RecordingError(
            f"recording {path} has no mask/ folder: the axis needs the object's mask per frame; "
            "record in simulation (`deploy sim record`) or add masks with a segmenter first"
        )
    pipe = AxisPipeline(config)
    steps, final = [], None
    for i in range(len(recording)):
        frame = recording.frame(i)
        pose = recording.records[i].get("ee_pose")
        step = pipe.update_frame(frame, frame.mask, None if pose is None else np.asarray(pose))
        final = step.result
        entry = {"frame": frame.index, "joint_type": None, "origin": None, "direction": None,
                 "moving_points": step.moving_points}
        if isinstance(step.result, Axis):
            entry.update({k: v for k, v in step.result.to_dict().items() if k in ("joint_type", "origin", "direction")})
        else:
            entry["reason"] = step.result.reason
        steps.append(entry)
    out = {
        "estimator": config.estimator.name, "joint_type": None, "origin": None, "direction": None,
        "radius": None, "residual_m": None, "n_samples": len(recording),
        "frame": "base" if recording.T_base_camera is not None else "camera", "steps": steps,
    }
    if isinstance(final, Axis):
        out.update(final.to_dict())
    else:
        out["reason"] = final.reason if final is not None else "recording has no frames"
    return out
