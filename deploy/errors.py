"""One exception family per kind of failure; every message names the thing, the cause and the fix."""

from drivers.errors import ArmError, CameraError, DriverError, RecordingError


class AxisloopError(Exception):
    """Base class for errors raised above the drivers; the CLI prints them as one clear line."""


class ConfigError(AxisloopError):
    """An invalid or missing configuration file or option."""


class PerceptionError(AxisloopError):
    """Segmentation or tracking failed, or a model is missing."""


class CalibrationError(AxisloopError):
    """A calibration that cannot be computed, loaded or trusted."""


USER_ERRORS = (AxisloopError, DriverError)

__all__ = [
    "AxisloopError", "ConfigError", "PerceptionError", "CalibrationError",
    "ArmError", "CameraError", "DriverError", "RecordingError", "USER_ERRORS",
]
