"""The opening policy: grasp the handle, pull, estimate the joint axis, step along it until the target."""

from deploy.control.episode import EpisodeResult, run_episode
from deploy.control.policy import OpenConfig

__all__ = ["EpisodeResult", "OpenConfig", "run_episode"]
