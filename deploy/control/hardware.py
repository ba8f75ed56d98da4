"""`deploy open* --camera d415|replay:PATH --arm can|ideal`: the episode on a real (or recorded) camera and arm.

The camera pose in the arm's base frame comes from the frames themselves (a frames-directory recording
stores it) or from the hand-eye calibration of this camera and robot (`deploy calibrate hand-eye`). A real
arm asks for confirmation before its first motion (skip with --yes); --dry-run plans and moves nothing.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import typer

from deploy.control.episode import run_episode
from deploy.control.policy import OpenConfig
from deploy.control.session import OpenRequest
from deploy.control.viewer import RerunViewer
from deploy.errors import CalibrationError, ConfigError
from deploy.perception import make_segmenter
from drivers.arm.base import Arm
from drivers.arm.factory import DRIVER_ARMS, open_arm
from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import load_robot_config
from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.camera.factory import open_camera

JOINT_SPEED_SHARE = 0.3  # free-space moves at this share of the robot's joint velocity limits


class PosedCamera(Camera):
    """A camera whose frames get their pose in the base frame from `pose()` (the hand-eye calibration)."""

    def __init__(self, camera: Camera, pose: Callable[[], np.ndarray]) -> None:
        self.camera, self.pose = camera, pose

    @property
    def intrinsics(self) -> Intrinsics:
        return self.camera.intrinsics

    def connect(self) -> None:
        self.camera.connect()

    def disconnect(self) -> None:
        self.camera.disconnect()

    def read(self, timeout_s: float = 2.0) -> Frame:
        frame = self.camera.read(timeout_s)
        if frame.T_base_camera is None:
            frame.T_base_camera = self.pose()
        return frame


def open_on_hardware(request: OpenRequest) -> dict:
    """Run the request on the camera and arm it names; the episode's JSON result."""
    if request.arm not in DRIVER_ARMS:
        raise ConfigError(f"unknown arm {request.arm!r}: with --camera {request.camera} use one of "
                          f"{', '.join(DRIVER_ARMS)}")
    if request.robot is None:
        raise ConfigError(f"--arm {request.arm} needs --robot CONFIG.toml (see configs/robots/ and docs/arm.md)")
    robot = load_robot_config(request.robot)
    kin = robot.kinematics()
    camera = open_camera(request.camera)  # checks the spec; connects below
    segmenter = make_segmenter(request.segmenter or "gdino-sam2")
    config = OpenConfig(task=request.task, policy=request.policy, **request.options())
    run_dir = request.folder()
    viewer = RerunViewer(run_dir / "episode.rrd") if request.view else None
    with camera, open_arm(request.arm, robot) as arm:
        posed = PosedCamera(camera, _camera_pose(request, camera, robot.name, kin, arm))
        if request.arm == "can" and not (request.dry_run or request.yes):
            typer.confirm(f"The arm will grasp and pull the {request.task} in view. Area clear, arm supervised?",
                          abort=True)
        result = run_episode(posed, arm, kin, segmenter, config, run_dir,
                             robot.motion_limits(kin, JOINT_SPEED_SHARE), viewer=viewer)
    return {**result.to_dict(), "task": request.task, "camera": request.camera, "arm": request.arm,
            "policy": request.policy}


def _camera_pose(request: OpenRequest, camera: Camera, robot_id: str, kin: Kinematics,
                 arm: Arm) -> Callable[[], np.ndarray]:
    """T_base_camera for frames that do not carry it, from --calibration or this camera's saved calibration."""
    from calibration.store import load_for, load_hand_eye

    serial = getattr(camera, "serial", None)
    record = (load_hand_eye(request.calibration) if request.calibration is not None
              else load_for(serial, robot_id) if serial else None)

    def pose() -> np.ndarray:
        if record is None:
            raise CalibrationError(
                f"no hand-eye calibration for camera {serial or request.camera} on robot {robot_id!r}: run "
                "`deploy calibrate hand-eye` or give --calibration FILE")
        return record.T_base_camera(kin.fk(arm.state().q))

    return pose

