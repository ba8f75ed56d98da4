"""Cameras chosen by a string: `d415`, `d415:SERIAL`, `replay:PATH` (frames directory, .bag or .db3).

`sim` is not handled here (drivers import nothing above them): deploy builds the simulated camera.
"""

from __future__ import annotations

from pathlib import Path

from drivers.camera.base import Camera
from drivers.errors import CameraError

SPECS = ("d415", "d415:SERIAL", "replay:PATH")
_REPLAY_OPTIONS = {"realtime", "loop"}


def open_camera(spec: str, **options: object) -> Camera:
    """The camera named by `spec`, not yet connected (use `with open_camera(spec) as camera:`).

    options: for d415, RealSenseConfig / FilterConfig fields (width, height, fps, visual_preset,
    spatial, ...); for a frames directory, realtime and loop; for .bag/.db3, filters (a FilterConfig).
    """
    kind, _, arg = spec.partition(":")
    if kind == "d415":
        from drivers.camera.realsense import D415Camera
        from drivers.camera.realsense_config import RealSenseConfig

        return D415Camera(RealSenseConfig.from_options(serial=arg or None, **options))
    if kind == "replay" and arg:
        path = Path(arg)
        if path.suffix.lower() in (".bag", ".db3"):
            from drivers.camera.realsense_playback import RealSenseReplayCamera

            _check_options(spec, options, {"filters"})
            return RealSenseReplayCamera(path, **options)  # type: ignore[arg-type]
        from drivers.camera.frames_dir import FramesReplayCamera

        _check_options(spec, options, _REPLAY_OPTIONS)
        return FramesReplayCamera(path, **options)  # type: ignore[arg-type]
    raise CameraError(f"unknown camera {spec!r}; choose one of {', '.join(SPECS)} (or sim, where deploy offers it)")


def _check_options(spec: str, options: dict, allowed: set[str]) -> None:
    unknown = set(options) - allowed
    if unknown:
        raise CameraError(f"camera {spec!r}: unknown option(s) {', '.join(sorted(unknown))}; "
                          f"valid: {', '.join(sorted(allowed))}")
