"""`deploy cameras list|snapshot`, `deploy record` and `deploy convert`: RealSense discovery and recordings."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from deploy.commands.options import kind_option
from deploy.commands.output import console, print_json, print_table, progress_bar
from drivers.camera.registry import CAMERAS

if TYPE_CHECKING:
    from drivers.camera.base import Camera

app = typer.Typer(help="RealSense cameras: discovery and snapshots.", no_args_is_help=True)
top_level = typer.Typer()  # its commands sit directly under `deploy`

CameraSpecOpt = kind_option(CAMERAS, "--camera", " sim: a simulated drawer, seed 0.")
WidthOpt = Annotated[int, typer.Option(help="Image width (d415: 640, 848 or 1280; sim: any).")]
HeightOpt = Annotated[int, typer.Option(help="Image height (d415: 480 or 720).")]
FpsOpt = Annotated[int, typer.Option(help="Frames per second (d415: 6, 15, 30 or 60).")]
JsonTextOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of text.")]


@contextmanager
def open_any_camera(spec: str, width: int = 640, height: int = 480, fps: int = 30) -> Iterator[Camera]:
    """The camera `spec` names, connected, from the rig builder (`sim`: the simulated drawer scene of seed 0)."""
    from deploy.rig import RigSpec, open_rig
    from drivers.camera.registry import CAMERAS

    entry, _ = CAMERAS.entry(spec)
    options = {"width": width, "height": height, "fps": fps} if entry.name in ("d415", "sim") else {}
    with open_rig(RigSpec(camera=spec, arm=None, camera_options=options)) as rig:
        yield rig.camera


@app.command("list")
def list_cameras(json_out: JsonTextOpt = False) -> None:
    """List connected RealSense cameras: serial, name, firmware, USB type and supported profiles.

    Example: deploy cameras list --json
    """
    from drivers.camera.realsense_device import list_devices

    cameras = list_devices()
    if json_out:
        print_json({"cameras": cameras})
        return
    if not cameras:
        console.print("no RealSense camera connected")
        return
    print_table("RealSense cameras", ("serial", "name", "firmware", "usb_type", "profiles"),
                [(cam["serial"], cam["name"], cam["firmware"], cam["usb_type"], "\n".join(cam["profiles"]))
                 for cam in cameras])


@app.command("snapshot")
def snapshot(
    out: Annotated[Path, typer.Option(help="Directory to write color.png, depth.png, depth_color.png, "
                                           "intrinsics.json.")],
    camera: CameraSpecOpt = "d415",
    width: WidthOpt = 640,
    height: HeightOpt = 480,
    fps: FpsOpt = 30,
    json_out: JsonTextOpt = False,
) -> None:
    """Save one aligned colour/depth pair, a coloured depth PNG and the intrinsics.

    Example: deploy cameras snapshot --camera d415 --out snap
    """
    from drivers.camera.snapshot import save_snapshot

    with open_any_camera(camera, width, height, fps) as cam, cam:
        frame = cam.read()
        files = save_snapshot(frame, out, getattr(cam, "depth_scale", 0.001))
    if json_out:
        print_json({"files": [str(f) for f in files], "intrinsics": frame.intrinsics.to_dict()})
    else:
        console.print(f"wrote {', '.join(str(f) for f in files)}")


@top_level.command("record")
def record_cmd(
    out: Annotated[Path, typer.Option(help="Frames directory to write (docs/recording-format.md).")],
    camera: CameraSpecOpt = "d415",
    seconds: Annotated[float | None, typer.Option(help="Camera seconds to record.")] = None,
    frames: Annotated[int | None, typer.Option(help="Frames to record.")] = None,
    width: WidthOpt = 640,
    height: HeightOpt = 480,
    fps: FpsOpt = 30,
    json_out: JsonTextOpt = False,
) -> None:
    """Record a camera to a frames directory, flushing every frame (Ctrl-C keeps what was recorded).

    Example: deploy record --camera d415 --out runs/rec1 --seconds 10
    """
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    from deploy.errors import RecordingError
    from drivers.camera.record import record

    if seconds is None and frames is None:
        raise RecordingError("deploy record: say how long to record with --seconds S or --frames N")
    columns = (TextColumn("recording"), BarColumn(), TextColumn("{task.completed} frames"), TimeElapsedColumn())
    with progress_bar("record", frames, *columns) as bar, open_any_camera(camera, width, height, fps) as cam:
        summary = record(cam, out, frames=frames, seconds=seconds, progress=bar.advance)
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s) to {out}")


@top_level.command("convert")
def convert(
    recording: Annotated[Path, typer.Argument(help="RealSense recording (.bag or .db3).")],
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    depth_scale: Annotated[float, typer.Option(help="Depth unit of the frames directory (m).")] = 0.001,
    json_out: JsonTextOpt = False,
) -> None:
    """Convert a RealSense .bag/.db3 recording into a frames directory (depth aligned to colour).

    Example: deploy convert session.db3 --out runs/session
    """
    from drivers.camera.realsense_convert import convert_recording

    with progress_bar(f"converting {recording.name}") as bar:
        summary = convert_recording(recording, out, depth_scale, progress=bar.advance)
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s) to {out} "
                      f"(source depth unit {summary['source_depth_scale']:g} m)")

