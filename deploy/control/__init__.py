"""The opening policy: grasp the handle, pull, estimate the joint axis, step along it until the target."""

from deploy.control.episode import run_episode
from deploy.control.state import EpisodeResult, StopReason

__all__ = ["EpisodeResult", "StopReason", "run_episode"]
