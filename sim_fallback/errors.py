"""Errors of the simulated world's set-up: user errors (the CLI prints them as one line, exit 2)."""

from drivers.errors import DriverError


class SceneError(DriverError):
    """A scene that cannot be built as asked (an unknown world, a part the furniture does not have, no part within
    the robot's reach); the message names the thing, the cause and the fix."""


class PartError(SceneError):
    """The furniture has no part as asked, or none within the robot's reach."""
