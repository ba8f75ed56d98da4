"""The run folder of one episode: what the camera saw (frames directory), steps.json and report.png.

    RUN/frames/      frames-directory recording (colour, depth, segmenter mask, ee_pose, joint_positions,
                     joint_commands, gripper_width_m, and `grasped`: false on the first frames, true on the pulls'
                     while the gripper holds; meta.json names the robot config); every command that reads a
                     recording takes RUN for it (`deploy axis estimate RUN`)
    RUN/config.json  the resolved run config the episode used (every section, the filter profile the camera
                     chose, `filter_used`: the radius in metres and eps, and `acted_with`: the estimator and
                     fusion the policy acted with; `perception.point`: the pixel the user pointed at), written
                     with the first frame, and `scene`: the pointer and where it came from, in simulation the
                     world, furniture, assets folder, object, scale, part and the sensor models in force
    RUN/steps.json   result, the `scene` again, axis estimate per step, commanded and measured gripper poses per
                     motion (`t` from the motion's start, `start_s` on the episode's arm clock, as report.png's
                     opening curve), and a CAN arm's final motor states (`motors`: name, CAN id, enabled, status)
    RUN/report.png   axis estimates over the first colour frame, opening vs time, axis error per step
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from deploy.control.state import EpisodeResult
from deploy.geometry.types import Axis, JointType
from deploy.report.episode_plot import write_report
from drivers.arm.base import ArmState
from drivers.arm.motion import PathResult
from drivers.camera.base import Frame
from drivers.camera.frames_dir import FramesWriter

if TYPE_CHECKING:
    from deploy.config import Config

CONFIG_FILE = "config.json"


class RunFolder:
    """Writes one episode's run folder as it goes; `finish` adds steps.json and the PNG report."""

    def __init__(self, path: Path, camera: str | None = None, simulated: bool = False,
                 config: Config | None = None, scene: dict | None = None, robot: str | None = None) -> None:
        """`camera`: the camera spec, and whether it is `simulated`, stored with the frames (they pick the
        recording's filter profile when it is replayed); `config`: the resolved run config, kept as
        config.json; `scene`: what the episode was given and met (JSON values), kept in config.json and
        steps.json; `robot`: the robot config the joints belong to (its name or file), stored with the frames."""
        self.camera, self.simulated, self.scene, self.robot = camera, simulated, scene or {}, robot
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        self._writer: FramesWriter | None = None
        self.motions: list[dict] = []
        self._config = config  # written with the first frame (a run refused before it leaves the folder empty)

    def write_config(self, config: Config) -> None:
        """RUN/config.json: `config` as the episode used it (JSON: no value is left out, None is null)."""
        used = config.filter.resolve()
        data = {**config.model_dump(mode="json"), "filter_used": {"radius_m": used.radius_m, "eps": used.eps},
                "acted_with": {"estimator": config.acting_estimator, "fusion": config.opening.acting_fusion},
                "scene": self.scene}
        (self.path / CONFIG_FILE).write_text(json.dumps(data, indent=1) + "\n")
        self._config = None

    def write_frame(self, frame: Frame, mask: np.ndarray, arm: ArmState, ee_pose: np.ndarray,
                    first: bool = False, grasped: bool | None = None, commanded: np.ndarray | None = None) -> None:
        """Append one frame to RUN/frames with the arm's joints and gripper opening and the joints `commanded`
        (`first`: the body box was fixed on it; `grasped`: the gripper held the handle, written when given)."""
        if self._config is not None:
            self.write_config(self._config)
        if self._writer is None:
            self._writer = FramesWriter(self.path / "frames", frame.intrinsics, T_base_camera=frame.T_base_camera,
                                        camera=self.camera, simulated=self.simulated, robot=self.robot)
        self._writer.write(frame, mask=mask, joint_positions=arm.q, ee_pose=ee_pose, first=first, grasped=grasped,
                           joint_commands=commanded, gripper_width_m=arm.gripper_width_m)

    def add_motion(self, label: str, result: PathResult, start_s: float) -> None:
        """Keep one motion for steps.json: `start_s` is the episode's arm time at its start, `t` its own clock."""
        self.motions.append({"label": label, "reason": result.reason, "start_s": start_s, "t": result.t.tolist(),
                             "commanded": result.planned.tolist(), "measured": result.measured.tolist()})

    def finish(self, result: EpisodeResult, axis_error: Callable[[Axis], tuple[float, float]] | None = None,
               motors: list[dict] | None = None) -> None:
        """Close the recording and write steps.json and report.png (axis errors only with `axis_error`, which
        evaluation passes in simulation; `motors`: the arm's final motor states, as in the episode's JSON, kept
        when it has any)."""
        if self._config is not None:
            self.write_config(self._config)
        if self._writer is not None:
            self._writer.close()
        errors = [None if e["axis"] is None or axis_error is None else axis_error(_axis(e["axis"]))
                  for e in result.estimates]
        steps = [{**e, "axis_angle_error_deg": None if err is None else err[0],
                  "axis_position_error_m": None if err is None else err[1]}
                 for e, err in zip(result.estimates, errors, strict=True)]
        data = {"result": result.to_dict(), "scene": self.scene, "steps": steps, "motions": self.motions}
        if motors:
            data["motors"] = motors
        (self.path / "steps.json").write_text(json.dumps(data, indent=1) + "\n")
        write_report(self.path / "report.png", result, errors, truth=axis_error is not None)


def _axis(d: dict) -> Axis:
    return Axis(JointType(d["joint_type"]), np.array(d["origin"]), np.array(d["direction"]))
