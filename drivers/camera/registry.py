"""The camera kinds (`--camera`): a RealSense D415 and recordings; other packages add theirs (the simulated
D415 registers from sim_fallback). `open_camera(spec)` builds one, not yet connected."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from drivers.errors import CameraError
from drivers.registry import Registry

if TYPE_CHECKING:
    from drivers.camera.base import Camera

CAMERAS: Registry[Camera] = Registry("camera", CameraError)  # factories: factory(argument, **options)
CAMERAS.register("d415", "drivers.camera.registry:open_d415", "RealSense D415 (first attached, or SERIAL)",
                 argument="[:SERIAL]", hardware=True)
CAMERAS.register("replay", "drivers.camera.registry:open_replay",
                 "a recording (frames dir, .bag, .db3)", argument=":PATH")
_REPLAY_OPTIONS = {"realtime", "loop"}


def open_camera(spec: str, **options: object) -> Camera:
    """The camera named by `spec`, not yet connected (use `with open_camera(spec) as camera:`).

    options: for d415, RealSenseConfig / FilterConfig fields (width, height, fps, visual_preset, spatial, ...);
    for a frames directory, realtime and loop; for .bag/.db3, filters (a FilterConfig).
    """
    return CAMERAS.open(spec, **options)


def open_d415(serial: str, **options: object) -> Camera:
    from drivers.camera.realsense import D415Camera
    from drivers.camera.realsense_config import RealSenseConfig

    return D415Camera(RealSenseConfig.from_options(serial=serial or None, **options))


def open_replay(path: str, **options: object) -> Camera:
    file = Path(path)
    if file.suffix.lower() in (".bag", ".db3"):
        from drivers.camera.realsense_playback import RealSenseReplayCamera

        _check_options(path, options, {"filters"})
        return RealSenseReplayCamera(file, **options)  # type: ignore[arg-type]
    from drivers.camera.frames_dir import FramesReplayCamera

    _check_options(path, options, _REPLAY_OPTIONS)
    return FramesReplayCamera(file, **options)  # type: ignore[arg-type]


def _check_options(path: str, options: dict, allowed: set[str]) -> None:
    unknown = set(options) - allowed
    if unknown:
        raise CameraError(f"camera replay:{path}: unknown option(s) {', '.join(sorted(unknown))}; "
                          f"valid: {', '.join(sorted(allowed))}")
