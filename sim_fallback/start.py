"""What every simulated episode starts from, whatever its world: the arm's start configuration and the target
joint's condition."""

from __future__ import annotations

from typing import Literal

import numpy as np

Condition = Literal["normal", "locked", "stiff"]  # the object's joint: as drawn, held fast, 3x the friction
CONDITIONS: tuple[Condition, ...] = ("normal", "locked", "stiff")
# Start: the hand retracted 0.3 m in front of the base at 0.75 m height, approach along +x (the ready
# pose's orientation), clear of any cabinet front; jittered per scenario.
Q_START = np.array([0.0, -1.2523, 0.0, -2.6382, 0.0, 2.9565, 0.7854])
START_JITTER_RAD = 0.05  # std of the start configuration around Q_START


def random_start(rng: np.random.Generator) -> tuple[float, ...]:
    """The arm's start configuration (rad): Q_START jittered (it stays well inside the limits)."""
    return tuple(float(v) for v in Q_START + rng.normal(0.0, START_JITTER_RAD, Q_START.shape))
