"""`deploy record`: a camera, and optionally the arm beside it, to a frames directory (docs/recording-format.md).

The rig opens both (`RigSpec(camera=..., arm=...)`); with an arm, every frame stores the arm's joint positions
and its tool pose in the base frame (`joint_positions`, `ee_pose`), which `deploy axis estimate` fits as the
gripper's path. The arm is never enabled: it is read as it stands or as it is moved (by hand, or by another
program); a CAN arm's motors are asked for one feedback frame per camera frame.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from deploy.errors import ConfigError
from deploy.rig import Rig, RigSpec, SimScene, open_rig
from drivers.camera.base import Frame
from drivers.camera.record import ArmReading, record
from drivers.camera.registry import CAMERAS, check_stream_size, simulated_source, stream_options

VIEW_FILE = "recording.rrd"  # in the recording's folder, with --view


def record_rig(camera: str, out: Path, frames: int | None = None, seconds: float | None = None,
               arm: str | None = None, robot: Path | None = None, camera_options: dict[str, Any] | None = None,
               progress: Callable[[Frame], None] | None = None, view: bool = False,
               calibration: Path | None = None, sim_faults: list | None = None, can: tuple = (),
               world: str = "kitchen") -> dict:
    """Record `camera` (a registry spec) to `out` for `frames` frames or `seconds` s, with `arm`'s joint states
    and tool pose per frame when given; `view` also shows the frames in rerun and saves OUT/recording.rrd.
    `calibration`: the hand-eye file giving a real camera's pose (default: the one saved for it and the robot);
    a camera on the arm (eye-in-hand) gets its pose per frame from the arm's tool pose (`deploy.rig`).
    `sim_faults` (`--sim-fault`, arm sim-can): each breaks the simulated motors SECONDS into the recording; `can`:
    the command line's [can] settings over the robot config's; `world`: the simulated camera's (the drawer scene of
    seed 0 in it).
    Returns {"out", "frames", "seconds", "arm", "camera", "simulated"} (and "rrd" with `view`)."""
    _check_calibration(camera, arm, calibration)
    options = stream_options(camera, camera_options or {})
    viewer = None
    if view:
        from deploy.report.viewer import RerunViewer

        viewer = RerunViewer(out / VIEW_FILE)
    with open_rig(RigSpec(camera=camera, arm=arm, robot=robot, can=can, calibration=calibration,
                          camera_options=options, scene=SimScene(world=world))) as rig:
        check_stream_size(camera, camera_options or {}, rig.camera)

        latest: dict[str, np.ndarray] = {}  # the arm's last reading: the tool pose shown with its frame
        faults = _sim_faults_by_frame(rig, sim_faults or [])

        robot_shown: list[bool] = []

        def each(frame: Frame) -> None:
            if faults is not None:
                faults(frame)
            if viewer is not None:  # its file goes into the recording's folder: opened once the recording is there
                if "q" in latest and not robot_shown:
                    viewer.robot(rig.robot.urdf_path(), rig.robot.joint_names, rig.robot.locked_joints)
                    robot_shown.append(True)
                viewer.frame(frame.t, frame, frame.mask, latest.get("tool"))
                if "q" in latest:
                    viewer.arm(frame.t, latest["q"])
            if progress is not None:
                progress(frame)

        reading = _arm_reading(rig, latest) if arm is not None else None
        simulated = simulated_source(camera)
        try:
            summary = record(rig.camera, out, frames, seconds, progress=each, source=camera, simulated=simulated,
                             arm=reading, robot=rig.robot.reference if arm is not None else None)
        finally:
            if viewer is not None:
                viewer.close()
    summary.update({"camera": camera, "simulated": simulated})
    if viewer is not None:
        summary["rrd"] = str(out / VIEW_FILE)
    return summary


def _sim_faults_by_frame(rig: Rig, faults: list) -> Callable[[Frame], None] | None:
    """--sim-fault while recording: the arm is read, never run, so its own clock stands still; a fault at 0 s
    breaks the motors now, the others after the first frame at or past their SECONDS (camera time)."""
    if not faults:
        return None
    from dataclasses import replace

    from deploy.arm_bringup import inject_sim_faults

    inject_sim_faults(rig.arm, [f for f in faults if f.at_s == 0])
    pending, start = [f for f in faults if f.at_s > 0], []

    def inject(frame: Frame) -> None:
        start[:] = start or [frame.t]
        due = [f for f in pending if f.at_s <= frame.t - start[0]]
        pending[:] = [f for f in pending if f not in due]
        inject_sim_faults(rig.arm, [replace(f, at_s=0.0) for f in due])

    return inject


def _check_calibration(camera: str, arm: str | None, calibration: Path | None) -> None:
    """--calibration only where it is used: a real camera with an arm."""
    if calibration is None:
        return
    if CAMERAS.entry(camera)[0].simulated:
        raise ConfigError(f"--calibration {calibration} is for a real camera: the simulated camera's pose comes "
                          "from the simulation; drop --calibration, or use --camera d415")
    if arm is None:
        raise ConfigError(f"--calibration {calibration} places the camera in the arm's base frame: add --arm KIND "
                          "--robot CONFIG, or drop --calibration")


def _arm_reading(rig: Rig, latest: dict[str, np.ndarray]) -> ArmReading:
    """The arm's joint positions and tool pose, read without enabling it (the pose also kept in `latest`)."""
    arm, kin = rig.arm, rig.kin

    def read() -> tuple[np.ndarray, np.ndarray]:
        arm.probe()  # a CAN arm asks every motor for one feedback frame
        q = np.asarray(arm.state().q, float)
        latest["tool"], latest["q"] = kin.fk(q), q
        return q, latest["tool"]

    return read
