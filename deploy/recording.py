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

from deploy.rig import Rig, RigSpec, open_rig
from drivers.camera.base import Frame
from drivers.camera.record import ArmReading, record
from drivers.camera.registry import CAMERAS, simulated_source

VIEW_FILE = "recording.rrd"  # in the recording's folder, with --view


def record_rig(camera: str, out: Path, frames: int | None = None, seconds: float | None = None,
               arm: str | None = None, robot: Path | None = None, camera_options: dict[str, Any] | None = None,
               progress: Callable[[Frame], None] | None = None, view: bool = False) -> dict:
    """Record `camera` (a registry spec) to `out` for `frames` frames or `seconds` s, with `arm`'s joint states
    and tool pose per frame when given; `view` also shows the frames in rerun and saves OUT/recording.rrd.
    Returns {"out", "frames", "seconds", "arm", "camera", "simulated"} (and "rrd" with `view`)."""
    options = dict(camera_options or {})
    if CAMERAS.entry(camera)[0].name not in ("d415", "sim"):
        options = {}
    viewer = None
    if view:
        from deploy.control.viewer import RerunViewer

        viewer = RerunViewer(out / VIEW_FILE)
    with open_rig(RigSpec(camera=camera, arm=arm, robot=robot, camera_options=options)) as rig:

        latest: dict[str, np.ndarray] = {}  # the arm's last reading: the tool pose shown with its frame

        def each(frame: Frame) -> None:
            if viewer is not None:
                viewer.frame(frame.t, frame, frame.mask, latest.get("tool"))
            if progress is not None:
                progress(frame)

        reading = _arm_reading(rig, latest) if arm is not None else None
        simulated = simulated_source(camera)
        try:
            summary = record(rig.camera, out, frames, seconds, progress=each, source=camera, simulated=simulated,
                             arm=reading)
        finally:
            if viewer is not None:
                viewer.close()
    summary.update({"camera": camera, "simulated": simulated})
    if viewer is not None:
        summary["rrd"] = str(out / VIEW_FILE)
    return summary


def _arm_reading(rig: Rig, latest: dict[str, np.ndarray]) -> ArmReading:
    """The arm's joint positions and tool pose, read without enabling it (the pose also kept in `latest`)."""
    arm, kin = rig.arm, rig.kin
    refresh = getattr(arm, "probe", None)  # a CAN arm: one feedback frame from every motor

    def read() -> tuple[np.ndarray, np.ndarray]:
        if refresh is not None:
            refresh()
        q = np.asarray(arm.state().q, float)
        latest["tool"] = kin.fk(q)
        return q, latest["tool"]

    return read
