"""`deploy` commands for the cameras area: `cameras list|snapshot`, `record`, `convert`."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from drivers.camera.base import Camera

CameraSpecOpt = Annotated[str, typer.Option(
    "--camera", help="d415, d415:SERIAL, sim (simulated drawer, seed 0) or replay:PATH (frames dir, .bag, .db3).")]
WidthOpt = Annotated[int, typer.Option(help="Image width (d415: 640, 848 or 1280; sim: any).")]
HeightOpt = Annotated[int, typer.Option(help="Image height (d415: 480 or 720).")]
FpsOpt = Annotated[int, typer.Option(help="Frames per second (d415: 6, 15, 30 or 60).")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of text.")]


@contextmanager
def open_any_camera(spec: str, width: int = 640, height: int = 480, fps: int = 30) -> Iterator[Camera]:
    """A camera from `spec` (see --camera), not yet connected; `sim` is a static simulated drawer scene."""
    if spec == "sim":
        from sim_fallback.camera import SimCamera, d415_intrinsics
        from sim_fallback.scenario import Scenario
        from sim_fallback.world import SimWorld

        with SimWorld(Scenario.make("drawer", 0, "train")) as world:
            yield SimCamera(world, intrinsics=d415_intrinsics(width, height), fps=fps)
        return
    from drivers.camera.factory import open_camera

    options = {"width": width, "height": height, "fps": fps} if spec.partition(":")[0] == "d415" else {}
    yield open_camera(spec, **options)


def list_cameras(json_out: JsonOpt = False) -> None:
    """List connected RealSense cameras: serial, name, firmware, USB type and supported profiles.

    Example: deploy cameras list --json
    """
    from deploy.cli import _print_json, console
    from drivers.camera.realsense_device import list_devices

    cameras = list_devices()
    if json_out:
        _print_json({"cameras": cameras})
        return
    if not cameras:
        console.print("no RealSense camera connected")
        return
    from rich.table import Table

    table = Table(title="RealSense cameras")
    for col in ("serial", "name", "firmware", "usb_type", "profiles"):
        table.add_column(col)
    for cam in cameras:
        table.add_row(cam["serial"], cam["name"], cam["firmware"], cam["usb_type"], "\n".join(cam["profiles"]))
    console.print(table)


def snapshot(
    out: Annotated[Path, typer.Option(help="Directory to write color.png, depth.png, depth_color.png, "
                                           "intrinsics.json.")],
    camera: CameraSpecOpt = "d415",
    width: WidthOpt = 640,
    height: HeightOpt = 480,
    fps: FpsOpt = 30,
    json_out: JsonOpt = False,
) -> None:
    """Save one aligned colour/depth pair, a coloured depth PNG and the intrinsics.

    Example: deploy cameras snapshot --camera d415 --out snap
    """
    from deploy.cli import _print_json, console
    from drivers.camera.snapshot import save_snapshot

    with open_any_camera(camera, width, height, fps) as cam, cam:
        frame = cam.read()
        files = save_snapshot(frame, out, getattr(cam, "depth_scale", 0.001))
    if json_out:
        _print_json({"files": [str(f) for f in files], "intrinsics": frame.intrinsics.to_dict()})
    else:
        console.print(f"wrote {', '.join(str(f) for f in files)}")


def record_cmd(
    out: Annotated[Path, typer.Option(help="Frames directory to write (docs/recording-format.md).")],
    camera: CameraSpecOpt = "d415",
    seconds: Annotated[float | None, typer.Option(help="Camera seconds to record.")] = None,
    frames: Annotated[int | None, typer.Option(help="Frames to record.")] = None,
    width: WidthOpt = 640,
    height: HeightOpt = 480,
    fps: FpsOpt = 30,
    json_out: JsonOpt = False,
) -> None:
    """Record a camera to a frames directory, flushing every frame (Ctrl-C keeps what was recorded).

    Example: deploy record --camera d415 --out runs/rec1 --seconds 10
    """
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from deploy.cli import _print_json, console, err_console
    from deploy.errors import RecordingError
    from drivers.camera.record import record

    if seconds is None and frames is None:
        raise RecordingError("deploy record: say how long to record with --seconds S or --frames N")
    columns = (TextColumn("recording"), BarColumn(), TextColumn("{task.completed} frames"), TimeElapsedColumn())
    with Progress(*columns, console=err_console, transient=True) as bar, open_any_camera(camera, width, height,
                                                                                       fps) as cam:
        job = bar.add_task("record", total=frames)
        summary = record(cam, out, frames=frames, seconds=seconds,
                         progress=lambda frame: bar.update(job, advance=1))
    if json_out:
        _print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s) to {out}")


def convert(
    recording: Annotated[Path, typer.Argument(help="RealSense recording (.bag or .db3).")],
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    depth_scale: Annotated[float, typer.Option(help="Depth unit of the frames directory (m).")] = 0.001,
    json_out: JsonOpt = False,
) -> None:
    """Convert a RealSense .bag/.db3 recording into a frames directory (depth aligned to colour).

    Example: deploy convert session.db3 --out runs/session
    """
    from rich.progress import Progress

    from deploy.cli import _print_json, console, err_console
    from drivers.camera.realsense_convert import convert_recording

    with Progress(console=err_console, transient=True) as bar:
        job = bar.add_task(f"converting {recording.name}", total=None)
        summary = convert_recording(recording, out, depth_scale, progress=lambda frame: bar.advance(job))
    if json_out:
        _print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s) to {out} "
                      f"(source depth unit {summary['source_depth_scale']:g} m)")


def register(app: typer.Typer, bench_app: typer.Typer) -> None:
    """Add this area's commands to the main app and to `deploy bench`."""
    cameras_app = typer.Typer(help="RealSense cameras: discovery and snapshots.", no_args_is_help=True)
    cameras_app.command("list")(list_cameras)
    cameras_app.command("snapshot")(snapshot)
    app.add_typer(cameras_app, name="cameras")
    app.command("record")(record_cmd)
    app.command("convert")(convert)
