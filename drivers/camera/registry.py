"""The camera kinds (`--camera`): any RealSense, each model of the model table by its name (d415, d435, d455, d405,
l515: its defaults), and recordings; other packages add theirs (the simulated D415 registers from sim_fallback).
`open_camera(spec)` builds one, not yet connected."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from drivers.camera.realsense_models import models, size_text
from drivers.errors import CameraError
from drivers.registry import Registry

if TYPE_CHECKING:
    from drivers.camera.base import Camera

CAMERAS: Registry[Camera] = Registry("camera", CameraError)  # factories: factory(argument, **options)
STREAM_OPTIONS = ("width", "height", "fps")  # what `--width --height --fps` set, on kinds that take them
CAMERAS.register("realsense", "drivers.camera.registry:open_realsense",
                 "any RealSense (the one attached, or SERIAL), with its model's defaults", argument="[:SERIAL]",
                 hardware=True, stream_options=STREAM_OPTIONS)


def _register_models() -> None:
    """Each model of the model table under its name: a RealSense of that model, with its defaults."""
    for model in models().values():
        default = model.default
        CAMERAS.register(model.name, "drivers.camera.registry:open_realsense",
                         f"{model.product.removeprefix('Intel ')} ({size_text(default.color)} at {default.fps} fps)",
                         argument="[:SERIAL]", hardware=True, stream_options=STREAM_OPTIONS,
                         factory_options={"model": model.name})


_register_models()
CAMERAS.register("replay", "drivers.camera.registry:open_replay",
                 "a recording (frames dir; RealSense .bag/.db3; ROS 2 bag .db3/.mcap/folder)", argument=":PATH")
_REPLAY_OPTIONS = {"realtime", "loop"}


def open_camera(spec: str, **options: object) -> Camera:
    """The camera named by `spec`, not yet connected (use `with open_camera(spec) as camera:`).

    options: for a RealSense, RealSenseConfig / FilterConfig fields (width, height, fps, visual_preset, spatial,
    ...);
    for a frames directory, realtime and loop; for a RealSense .bag/.db3, filters (a FilterConfig).
    """
    return CAMERAS.open(spec, **options)


def stream_options(spec: str, options: dict[str, object]) -> dict[str, object]:
    """Those of `options` (width, height, fps) that camera `spec`'s kind takes, None ones left out (the kind's
    default); a recording takes none: `check_stream_size` refuses a size it cannot give."""
    entry, _ = CAMERAS.entry(spec)
    return {k: v for k, v in options.items() if k in entry.stream_options and v is not None}


def check_stream_size(spec: str, options: dict[str, object], camera: Camera) -> None:
    """A camera whose kind takes no size (a recording: it plays at the size it was recorded, never resized) must
    not be asked for another: CameraError naming both sizes when `options`' width or height (None: not asked)
    differ from `camera`'s (connected)."""
    entry, _ = CAMERAS.entry(spec)
    asked = {k: options.get(k) for k in ("width", "height") if options.get(k) is not None}
    if not asked or "width" in entry.stream_options:
        return
    intrinsics = camera.intrinsics
    if asked.get("width", intrinsics.width) != intrinsics.width or \
            asked.get("height", intrinsics.height) != intrinsics.height:
        given = " ".join(f"--{k} {v}" for k, v in asked.items())
        raise CameraError(f"camera {spec} plays its recording at {intrinsics.width}x{intrinsics.height}, not {given} "
                          "(a replay is never resized): drop --width and --height")


def simulated_source(spec: str) -> bool:
    """Whether the frames of camera `spec` come from a simulation: a simulated kind, or a replay of a frames
    recording made in simulation (its meta.json says so). Real cameras and RealSense recordings are not."""
    entry, argument = CAMERAS.entry(spec)
    if entry.simulated:
        return True
    from drivers.camera.realsense_convert import recording_kind

    if entry.name != "replay" or recording_kind(Path(argument)) != "frames" or not Path(argument).is_dir():
        return False
    from drivers.camera.frames_dir import FramesRecording

    return FramesRecording(argument).simulated


def open_realsense(serial: str, **options: object) -> Camera:
    """A RealSense camera (`model`, a name of the model table, among `options`: only a camera of that model)."""
    from drivers.camera.realsense import RealSenseCamera
    from drivers.camera.realsense_config import RealSenseConfig

    return RealSenseCamera(RealSenseConfig.from_options(serial=serial or None, **options))


def open_replay(path: str, **options: object) -> Camera:
    from drivers.camera.realsense_convert import recording_kind

    file = Path(path)
    kind = recording_kind(file)
    if kind == "realsense":
        from drivers.camera.realsense_playback import RealSenseReplayCamera

        _check_options(path, options, {"filters"})
        return RealSenseReplayCamera(file, **options)  # type: ignore[arg-type]
    if kind == "ros2":
        from drivers.camera.ros2_bag import Ros2BagCamera

        _check_options(path, options, set())
        return Ros2BagCamera(file)
    from drivers.camera.frames_dir import FramesReplayCamera

    _check_options(path, options, _REPLAY_OPTIONS)
    return FramesReplayCamera(file, **options)  # type: ignore[arg-type]


def _check_options(path: str, options: dict, allowed: set[str]) -> None:
    unknown = set(options) - allowed
    if unknown:
        raise CameraError(f"camera replay:{path}: unknown option(s) {', '.join(sorted(unknown))}; "
                          f"valid: {', '.join(sorted(allowed))}")
