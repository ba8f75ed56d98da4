"""The one error family of furniture models: a folder, object, file or part that cannot be used."""

from drivers.errors import DriverError


class PartNetError(DriverError):
    """A PartNet-Mobility folder, object or part that cannot be used; the message names it, the cause and the fix."""
