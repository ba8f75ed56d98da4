"""One `deploy open*` request: pick the camera, arm and segmenter it names, run the episode, return its JSON.

`--camera sim` runs the PyBullet scenario `seed` (camera and arm share one world); any other camera is
real hardware or a recording, with the arm from `--arm` and the camera pose from the hand-eye calibration.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Literal

from deploy.errors import ConfigError

SIM_ARMS = ("sim", "sim-can")


@dataclass(frozen=True)
class OpenRequest:
    """What the user asked for. task: what the policy is told ("auto" = classify from the probe pull);
    scene: the simulated object (`--camera sim` only)."""

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

    def options(self) -> dict:
        """OpenConfig fields of this request."""
        return {"target_distance_m": self.distance_m, "target_angle_deg": self.angle_deg, "dry_run": self.dry_run}

    def folder(self) -> Path:
        return self.run_dir or Path("runs") / f"{self.task}-{datetime.now():%Y%m%d-%H%M%S}"


def open_object(request: OpenRequest) -> dict:
    """Run the request; the episode's JSON result (simulation adds the truth-based fields)."""
    if request.camera == "sim":
        return _open_in_simulation(request)
    if request.arm in SIM_ARMS:
        raise ConfigError(f"--arm {request.arm} needs --camera sim (a simulated arm cannot act on what a real "
                          f"camera sees); use --arm can with --camera {request.camera}")
    from deploy.control.hardware import open_on_hardware

    return open_on_hardware(request)


def _open_in_simulation(request: OpenRequest) -> dict:
    from deploy.bench.open import simulate_episode

    if request.arm not in SIM_ARMS:
        raise ConfigError(f"--camera sim needs a simulated arm (--arm sim or sim-can), not {request.arm!r}")
    if request.segmenter not in (None, "oracle"):
        raise ConfigError(f"--camera sim uses the renderer's segmentation (oracle), not {request.segmenter!r}: "
                          "try other segmenters on a recording with `deploy track`")
    return simulate_episode(
        request.scene, request.seed, request.split, None, request.policy, run_dir=request.folder(),
        auto_joint=request.task == "auto", view=request.view, arm_kind=request.arm, **request.options(),
    )
