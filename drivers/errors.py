"""Driver-level errors (re-exported by deploy.errors so users catch one family per failure)."""


class DriverError(Exception):
    """Base class for hardware and recording failures; messages name the device, the cause and the fix."""


class CameraError(DriverError):
    """A camera that cannot be opened, times out or disappears."""


class RecordingError(DriverError):
    """A missing, corrupt or unreadable recording."""


class ArmError(DriverError):
    """An arm or CAN bus fault; the arm has been stopped when this is raised."""


class IKError(ArmError):
    """No joint configuration reaches a pose or follows a path (out of reach, a joint limit, a singularity)."""


class JointSpeedError(IKError):
    """A path's next pose needs a joint to move faster than its velocity limit allows (near a singularity): the
    same path followed more slowly may pass."""


class CalibrationError(DriverError):
    """A calibration that cannot be computed, loaded or trusted: board, views, pose set, solve or file."""


class CanBusError(ArmError):
    """The CAN bus itself failed (bus-off, error-passive, full transmit queue, adapter gone)."""
