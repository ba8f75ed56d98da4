"""The one episode builder of the tests that run `run_episode` themselves (a world changed first, a scenario or a
segmenter of their own): an arm of any registered kind built by its factory in the scenario's world, with its robot
config (free-space limits, grip force, compliance: as `deploy open` runs it), the simulated camera at its true pose
with the simulator's labels for the oracle segmenter. Tests of the whole request use `deploy.bench.open
.simulate_episode` instead."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from deploy.config import Config
from deploy.control.episode import run_episode
from deploy.control.state import EpisodeResult
from deploy.perception.base import Segmenter
from deploy.perception.oracle import OracleSegmenter
from deploy.report.run_folder import RunFolder
from drivers.arm.base import Arm
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import PANDA_SIM_CONFIG, RobotConfig, load_robot_config
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

PANDA = load_robot_config(PANDA_SIM_CONFIG)
STILL_RAD = 0.01  # the arm moved less than this in half a second after the episode: it was left stopped


@dataclass(frozen=True)
class SimEpisode:
    """How a simulated episode ended: its result, whether the arm stayed still afterwards, the true joint value."""

    result: EpisodeResult
    still: bool
    true_opening: float


def sim_episode(scenario: Scenario | None = None, arm: str = "sim", robot: RobotConfig = PANDA,
                target: float = 0.15, setup: Callable[[SimWorld, Arm], None] | None = None,
                segmenter: Segmenter | None = None, folder: RunFolder | None = None,
                resolution: tuple[int, int] = (320, 240)) -> SimEpisode:
    """`run_episode` on `scenario` (default: drawer seed 0 of the train split) to `target` (m or deg) with arm kind
    `arm` (opened from the registry, connected for the episode), after `setup(world, arm)`; the run `folder` is
    finished when given."""
    scenario = scenario or Scenario.make("drawer", 0, "train")
    goal = {"target_distance_m": target} if scenario.task == "drawer" else {"target_angle_deg": target}
    config = Config().replace(opening={"task": scenario.task, **goal})
    with SimWorld(scenario) as world:
        device = ARMS.open(arm, robot, world=world)
        camera = SimCamera(world, intrinsics=d415_intrinsics(*resolution), fps=config.opening.camera_hz, labels=True,
                           posed=True)
        with device:
            if setup is not None:
                setup(world, device)
            result = run_episode(camera, device, segmenter or OracleSegmenter(), config, robot, folder)
            if folder is not None:
                folder.finish(result, motors=device.motor_states())
            q0 = device.state().q
            world.clock.step(120)
            still = float(np.abs(device.state().q - q0).max()) < STILL_RAD
        return SimEpisode(result, still, world.joint_value())


def episode_running(monkeypatch) -> list[bool]:
    """A list that is non-empty exactly while a session's episode runs (deploy.control.session.run_episode)."""
    from deploy.control import session

    running: list[bool] = []
    real = session.run_episode

    def run(*args, **kwargs):
        running.append(True)
        try:
            return real(*args, **kwargs)
        finally:
            running.pop()

    monkeypatch.setattr(session, "run_episode", run)
    return running
