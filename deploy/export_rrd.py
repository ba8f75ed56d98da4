"""`deploy export --format rrd`: a frames recording as a rerun recording (deploy/report/viewer.py).

Every frame: colour, depth, the mask's outline, the camera's and the gripper's poses; with joints, the robot from
the URDF of the robot config the recording names (meta.json `robot`, or `--robot`) posed by them, and the joints,
their commands and the gripper's opening as scalars. A run folder's recording adds what its steps.json holds: each
motion's planned and executed tool paths, and at each step the axis acted on with its confidence and the object's
cloud of the step's latest frame.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from deploy.errors import RecordingError
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.types import Axis, JointType
from drivers.arm.robot_config import RobotConfig, load_robot_config
from drivers.camera.frames_dir import FramesRecording

Progress = Callable[[float, float], None]
STEPS_FILE = "steps.json"  # beside a run folder's recording (deploy/report/run_folder.py)


def write_rrd(rec: FramesRecording, out: Path, progress: Progress | None = None, robot: str | None = None) -> list[str]:
    """Write `rec` to the rerun file `out`; `robot` (a robot config's name or file) overrides the recording's."""
    from deploy.report.viewer import RerunViewer

    config = _robot(rec, robot)
    viewer = RerunViewer(out, spawn=False, name=f"axisloop {rec.path.name}")
    try:
        if config is not None:
            viewer.robot(config.urdf_path(), config.joint_names, config.locked_joints)
        for i in range(len(rec)):
            frame, record = rec.frame(i), rec.records[i]
            pose = record.get("ee_pose")
            viewer.frame(frame.t, frame, frame.mask, None if pose is None else np.asarray(pose))
            if "joint_positions" in record:
                viewer.arm(frame.t, np.asarray(record["joint_positions"]), record.get("joint_commands"),
                           record.get("gripper_width_m"))
            if progress is not None:
                progress(i + 1, len(rec))
        _log_steps(viewer, rec)
    finally:
        viewer.close()
    return [out.name]


def _robot(rec: FramesRecording, robot: str | None) -> RobotConfig | None:
    """The robot config the recording's joints belong to (None: no model to show); RecordingError when its joints
    do not match them."""
    name = robot or rec.robot
    if name is None:
        return None
    config = load_robot_config(name)
    joints = next((r["joint_positions"] for r in rec.records if "joint_positions" in r), None)
    if joints is not None and len(joints) != len(config.joint_names):
        raise RecordingError(f"recording {rec.path} has {len(joints)} joint values per frame but robot config "
                             f"{name} has {len(config.joint_names)} joints: pass --robot with the arm it was "
                             "recorded with")
    return config


def _log_steps(viewer, rec: FramesRecording) -> None:
    """A run folder's motions and steps (RUN/steps.json), when the recording is a run folder's."""
    file = rec.path.parent / STEPS_FILE
    if not file.is_file():
        return
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
        motions, steps = data.get("motions", []), data.get("steps", [])
    except (ValueError, AttributeError) as exc:
        raise RecordingError(f"{file} is not a run's steps.json ({exc}): restore it, or export the recording "
                             "without it (copy RUN/frames elsewhere)") from None
    for index, motion in enumerate(motions):
        viewer.motion(motion["start_s"] + motion["t"][-1], index, motion["label"], np.asarray(motion["commanded"]),
                      np.asarray(motion["measured"]))
    times = np.array([float(r["t"]) for r in rec.records])
    for step in steps:
        if step.get("axis") is None:
            continue
        a = step["axis"]
        axis = Axis(JointType(a["joint_type"]), np.asarray(a["origin"]), np.asarray(a["direction"]),
                    confidence=float(a.get("confidence", 0.0)))
        opened = step.get("opened_m", step.get("opened_deg"))
        viewer.axis(step["t"], axis, opened, step.get("source"), step.get("step"))
        latest = int(np.searchsorted(times, step["t"], side="right")) - 1
        frame = rec.frame(max(latest, 0))
        if frame.mask is not None:
            cloud = depth_to_points(frame.depth_m, frame.intrinsics.K, mask=frame.mask,
                                    T_base_camera=frame.T_base_camera)
            viewer.step_clouds(step["t"], cloud, None, None)
