"""One `deploy open*` request: build the rig it names, run the episode, finish the run folder, return the JSON.

In simulation the scenario's truth scores the episode afterwards (`deploy.evaluation`); the controller never
sees it. A real arm asks `confirm` before its first motion unless --yes or --dry-run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

from deploy.config import Config, load_config
from deploy.control.episode import run_episode
from deploy.control.run_folder import RunFolder
from deploy.rig import Rig, RigSpec, SimScene, open_rig
from drivers.camera.registry import CAMERAS

Setup = Callable[[Any, Any], None]  # (world, arm) -> None: changes a simulated world before the episode (tests)


@dataclass(frozen=True)
class OpenRequest:
    """What the user asked for. task: what the policy is told ("auto" = classify from the probe pull);
    scene: the simulated object (`--camera sim` only); config_file: a run's TOML (deploy/config.py);
    overrides: settings on top, by dotted name ({"opening.max_steps": 3, "estimator.name": "screw"})."""

    task: Literal["drawer", "door", "auto"]
    scene: Literal["drawer", "door"] = "drawer"
    distance_m: float = 0.30
    angle_deg: float = 45.0
    camera: str = "sim"
    arm: str = "sim"
    robot: Path | None = None
    calibration: Path | None = None
    segmenter: str | None = None
    seed: int = 0
    split: Literal["train", "test"] = "train"
    policy: Literal["closed", "open", "paper"] = "closed"
    run_dir: Path | None = None
    dry_run: bool = False
    yes: bool = False
    view: bool = False
    resolution: tuple[int, int] = (640, 480)
    config_file: Path | None = None
    overrides: dict[str, Any] = field(default_factory=dict)

    def config(self) -> Config:
        return load_config(self.config_file, {
            "opening.task": self.task, "opening.policy": self.policy, "opening.target_distance_m": self.distance_m,
            "opening.target_angle_deg": self.angle_deg, **self.overrides})

    def rig_spec(self, config: Config) -> RigSpec:
        simulated = CAMERAS.entry(self.camera)[0].simulated
        width, height = self.resolution
        return RigSpec(camera=self.camera, arm=self.arm, robot=self.robot, calibration=self.calibration,
                       segmenter=self.segmenter or ("oracle" if simulated else "gdino-sam2"),
                       perception=config.perception, scene=SimScene(self.scene, self.seed, self.split),
                       camera_options={"width": width, "height": height, "fps": config.opening.camera_hz}
                       if simulated else {})

    def folder(self) -> Path:
        return self.run_dir or Path("runs") / f"{self.task}-{datetime.now():%Y%m%d-%H%M%S}"


def open_object(request: OpenRequest, confirm: Callable[[str], None] | None = None,
                setup: Setup | None = None, keep_run_dir: bool = True) -> dict:
    """Run the request; the episode's JSON result (simulation adds the truth-based fields).

    confirm(question) is asked before a real arm's first motion (it aborts by raising); setup(world, arm)
    changes a simulated world before the episode; keep_run_dir False: no run folder (benchmarks)."""
    wall = time.perf_counter()
    config = request.config()
    run_dir = request.folder() if keep_run_dir else None
    folder = RunFolder(run_dir) if run_dir is not None else None
    with open_rig(request.rig_spec(config)) as rig:
        if setup is not None:
            setup(rig.world, rig.arm)
        evaluation = _evaluation(rig)
        if rig.real_arm and confirm is not None and not (request.dry_run or request.yes):
            confirm(f"The arm will grasp and pull the {request.task} in view. Area clear, arm supervised?")
        with rig.arm:
            result = run_episode(rig.camera, rig.arm, rig.kin, rig.segmenter, config, folder,
                                 rig.motion_limits(), _viewer(request, run_dir), request.dry_run)
        data = {**result.to_dict(), "task": request.task, "camera": request.camera, "arm": request.arm,
                "policy": request.policy}
        if evaluation is not None:
            data.update({"seed": request.seed, "split": request.split, "task": request.scene,
                         **evaluation.score(result, config.opening), "seconds": time.perf_counter() - wall})
    if folder is not None:
        folder.finish(result, evaluation.axis_error if evaluation is not None else None)
    return data


def _evaluation(rig: Rig):
    if rig.world is None:
        return None
    from deploy.evaluation import Evaluation

    return Evaluation(rig.world)


def _viewer(request: OpenRequest, run_dir: Path | None):
    if not request.view or run_dir is None:
        return None
    from deploy.control.viewer import RerunViewer

    return RerunViewer(run_dir / "episode.rrd")
