"""One exception family per kind of failure; every message names the thing, the cause and the fix."""

from drivers.errors import (
    ArmError,
    CalibrationError,
    CameraError,
    CanBusError,
    DriverError,
    IKError,
    RecordingError,
)


class AxisloopError(Exception):
    """Base class for errors raised above the drivers; the CLI prints them as one clear line."""


class ConfigError(AxisloopError):
    """An invalid or missing configuration file or option."""


class PerceptionError(AxisloopError):
    """Segmentation or tracking failed, or a model is missing."""


class PointerError(PerceptionError):
    """The user's pointer (a pixel, a box) does not lead to a front with a handle the arm can open: what was seen there
    and what to do."""


class PartHiddenError(PointerError):
    """The arm hides the pointed part (or the pixel itself): moving the arm aside and looking again may show it."""


class ModelError(PerceptionError):
    """A model checkpoint that is missing, incomplete or does not load."""


class JobError(AxisloopError):
    """A job of a benchmark executor failed; `job` holds its arguments, the original error is `__cause__`."""

    job: dict | None = None


USER_ERRORS = (AxisloopError, DriverError)

__all__ = [
    "AxisloopError", "ConfigError", "PerceptionError", "PointerError", "ModelError", "JobError", "CalibrationError",
    "ArmError", "IKError", "CanBusError", "CameraError", "DriverError", "RecordingError", "USER_ERRORS",
]
