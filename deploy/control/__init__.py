"""The opening policy: grasp the handle, pull, estimate the joint axis, step along it until the target.

`run_episode` is imported on first use: the state record and stop reasons (`deploy.control.state`) load without
the episode's stages, perception and geometry (real-device calibration scores nothing and needs none of them).

The modules import one way: grasp, classify, policy (pure decisions), view (step lines) <- state <- observer <-
context <- stages <- episode <- session.
"""

from deploy.control.state import EpisodeResult, StopReason

__all__ = ["EpisodeResult", "StopReason", "run_episode"]


def __getattr__(name: str) -> object:
    if name == "run_episode":
        from deploy.control.episode import run_episode

        return run_episode
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
