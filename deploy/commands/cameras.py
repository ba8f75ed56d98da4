"""`deploy cameras list|snapshot`, `deploy record`, `deploy convert` and `deploy export`: RealSense discovery and
recordings in and out."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from deploy.commands.options import (
    BitrateOpt,
    ChannelOpt,
    DataBitrateOpt,
    InterfaceOpt,
    JsonOpt,
    RobotOpt,
    SimFaultOpt,
    WorldChoice,
    WorldOpt,
    above,
    can_settings,
    kind_option,
    overwrite_option,
    view_option,
)
from deploy.commands.output import console, print_json, progress_bar
from drivers.arm.registry import ARMS
from drivers.camera.registry import CAMERAS

if TYPE_CHECKING:
    from drivers.camera.base import Camera

app = typer.Typer(help="RealSense cameras: discovery and snapshots.", no_args_is_help=True)
top_level = typer.Typer()  # its commands sit directly under `deploy`

CameraSpecOpt = kind_option(CAMERAS, "--camera", " sim: a simulated drawer, seed 0 (of --world, where given).")
WidthOpt = Annotated[int | None, typer.Option(min=1, max=8192, show_default=False, help=(
    "Image width: a RealSense model's colour resolutions (docs/cameras.md); sim: any \\[default: the model's; sim: "
    "640; a replay: the recording's, which it keeps]."))]
HeightOpt = Annotated[int | None, typer.Option(min=1, max=8192, show_default=False, help=(
    "Image height, with --width \\[default: the model's; sim: 480; a replay: the recording's, which it keeps]."))]
FpsOpt = Annotated[int, typer.Option(min=1, max=1000, help=(
    "Frames per second: a RealSense model's rates (docs/cameras.md); sim: up to 240, its physics rate; a replay "
    "keeps the recording's times."))]
OverwriteOpt = overwrite_option("recording at --out")
ArmRecordOpt = kind_option(ARMS, "--arm", " Recorded with every frame: joint positions and tool pose (the arm is "
                           "read, never enabled; --robot names its config).", optional=True)
ViewOpt = view_option("the frames, the camera and the tool pose")


@contextmanager
def open_any_camera(spec: str, width: int | None = None, height: int | None = None, fps: int = 30) -> Iterator[Camera]:
    """The camera `spec` names, connected, from the rig builder (`sim`: the simulated drawer scene of seed 0); width
    and height None: the kind's default (a replay's: the recording's; CameraError when asked for another)."""
    from deploy.rig import RigSpec, open_rig
    from drivers.camera.registry import check_stream_size, stream_options

    asked = {"width": width, "height": height, "fps": fps}
    with open_rig(RigSpec(camera=spec, arm=None, camera_options=stream_options(spec, asked))) as rig:
        check_stream_size(spec, asked, rig.camera)
        yield rig.camera


@app.command("list")
def list_cameras(json_out: JsonOpt = False) -> None:
    """List connected RealSense cameras: model, serial, firmware, USB type, colour intrinsics with the lens model,
    depth unit and minimum range at the model's default resolution, and the supported profiles.

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
    for cam in cameras:
        console.print("\n".join(camera_lines(cam)), markup=False, highlight=False)


def camera_lines(cam: dict) -> list[str]:
    """A camera of `list_devices` as text lines of at most 80 columns."""
    model = cam["model"].upper() if cam["model"] else "RealSense (not in the model table: --camera realsense)"
    stream = cam["stream"]
    lines = [f"{model} {cam['name']}", f"  serial {cam['serial']}, firmware {cam['firmware']}, USB {cam['usb_type']}"]
    intr = cam["intrinsics"]
    if intr is not None:
        lines.append(f"  colour {intr['width']}x{intr['height']} from the {cam['color_sensor']}: fx {intr['fx']:.2f} "
                     f"fy {intr['fy']:.2f} cx {intr['cx']:.2f} cy {intr['cy']:.2f}")
        coeffs = " ".join(f"{name} {c:.4g}" for name, c in zip(("k1", "k2", "p1", "p2", "k3"),
                                                               intr.get("coeffs", [0.0] * 5), strict=True))
        lines.append(f"  {intr.get('distortion', 'none')}: {coeffs}")
    if cam["depth_scale"] is not None:
        near = "" if cam["min_range_m"] is None else f", minimum range {cam['min_range_m']:.2f} m"
        lines.append(f"  depth unit {cam['depth_scale'] * 1000:.3g} mm at {stream['depth']}{near}")
    lines.append("  profiles:")
    lines += ["    " + line for line in _grouped_profiles(cam["profiles"])]
    return lines


def _grouped_profiles(profiles: list[str]) -> list[str]:
    """"Depth 640x480 Z16 @30" profiles as one wrapped line per stream and format: "Depth Z16: 640x480 @6/15/30"."""
    import textwrap

    rates: dict[tuple[str, str], dict[str, list[int]]] = {}
    for profile in profiles:
        stream, size, fmt, fps = profile.split()
        rates.setdefault((stream, fmt), {}).setdefault(size, []).append(int(fps.lstrip("@")))
    lines = []
    for (stream, fmt), sizes in rates.items():
        modes = ", ".join(f"{size} @{'/'.join(map(str, sorted(fps)))}" for size, fps in
                          sorted(sizes.items(), key=lambda item: -int(item[0].split("x")[0])))
        lines += textwrap.wrap(f"{stream} {fmt}: {modes}", 76, subsequent_indent="  ")
    return lines


SNAPSHOT = {"color.png": None, "depth.png": None, "depth_color.png": None, "intrinsics.json": None}
"""What `deploy cameras snapshot` writes into its folder (a deploy.output_folder layout)."""


def check_snapshot_folder(out: Path, overwrite: bool, camera: str) -> None:
    """RecordingError unless `out` may take a snapshot of `camera`: apart from the recording a replay reads, and
    new, an empty folder, or an earlier snapshot (nothing but SNAPSHOT's files) with `overwrite`."""
    from deploy.errors import RecordingError
    from deploy.output_folder import check_apart, replay_input, stranger

    check_apart(out, replay_input(camera))
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return
    if not out.is_dir():
        raise RecordingError(f"--out {out} is a file, not a snapshot folder: choose another path")
    found = stranger(out, SNAPSHOT)
    if found is not None:
        name = found.relative_to(out)
        raise RecordingError(f"--out {out} holds {name}, which deploy cameras snapshot never writes there: refusing "
                             f"to write into the folder, even with --overwrite; move {name} out, or choose another "
                             "--out")
    if not overwrite:
        raise RecordingError(f"--out {out}: a snapshot is already there: pass --overwrite to replace it, or choose "
                             "another --out")


@app.command("snapshot")
def snapshot(
    out: Annotated[Path, typer.Option(help="Directory to write color.png, depth.png, depth_color.png, "
                                           "intrinsics.json: new or empty, or an earlier snapshot with "
                                           "--overwrite.")],
    camera: CameraSpecOpt = "d415",
    width: WidthOpt = None,
    height: HeightOpt = None,
    fps: FpsOpt = 30,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an earlier snapshot at --out (its four "
                                            "files are written anew); without it an existing one is refused, and "
                                            "a folder holding any other file is refused even with it.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Save one aligned colour/depth pair, a coloured depth PNG and the intrinsics.

    Example: deploy cameras snapshot --camera d415 --out snap
    """
    from drivers.camera.snapshot import save_snapshot

    check_snapshot_folder(out, overwrite, camera)  # before the camera opens
    with open_any_camera(camera, width, height, fps) as cam, cam:
        frame = cam.read()
        files = save_snapshot(frame, out, cam.depth_scale)
    if json_out:
        print_json({"files": [str(f) for f in files], "intrinsics": frame.intrinsics.to_dict()})
    else:
        console.print(f"wrote {', '.join(str(f) for f in files)}")


@top_level.command("record")
def record_cmd(
    out: Annotated[Path, typer.Option(help="Frames directory to write (docs/recording-format.md).")],
    camera: CameraSpecOpt = "d415",
    arm: ArmRecordOpt = None,
    robot: RobotOpt = None,
    calibration: Annotated[Path | None, typer.Option(
        "--calibration", metavar="FILE", help="With --arm: hand-eye calibration giving the camera's pose per frame "
        "\\[default: the one saved for this camera and robot].")] = None,
    seconds: Annotated[float | None, typer.Option(callback=above(0.0), help="Camera seconds to record.")] = None,
    frames: Annotated[int | None, typer.Option(min=1, help="Frames to record.")] = None,
    width: WidthOpt = None,
    height: HeightOpt = None,
    fps: FpsOpt = 30,
    view: ViewOpt = False,
    overwrite: OverwriteOpt = False,
    interface: InterfaceOpt = None,
    channel: ChannelOpt = None,
    bitrate: BitrateOpt = None,
    data_bitrate: DataBitrateOpt = None,
    sim_fault: SimFaultOpt = None,
    world: WorldOpt = WorldChoice.kitchen,
    json_out: JsonOpt = False,
) -> None:
    """Record a camera to a frames directory, flushing every frame (Ctrl-C keeps what was recorded); with
    --arm, the arm's joint states and tool pose per frame too (the arm is read, never enabled).

    Example: deploy record --camera d415 --out runs/rec1 --seconds 10
    Example: deploy record --camera d415 --arm can --robot my_arm.toml --out runs/rec2 --seconds 20
    """
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    from deploy.arm_bringup import parse_sim_faults
    from deploy.errors import RecordingError
    from deploy.output_folder import new_output, replay_input
    from deploy.recording import record_rig

    if seconds is None and frames is None:
        raise RecordingError("deploy record: say how long to record with --seconds S or --frames N")
    faults = parse_sim_faults(arm or "none", sim_fault)  # SECONDS: into the recording (the arm is only read)
    columns = (TextColumn("recording"), BarColumn(), TextColumn("{task.completed} frames"), TimeElapsedColumn())
    with (new_output(out, overwrite, "recording", inputs=replay_input(camera)),
          progress_bar("record", frames, *columns) as bar):
        summary = record_rig(camera, out, frames, seconds, arm, robot, {"width": width, "height": height,
                                                                        "fps": fps}, bar.advance, view,
                              calibration, sim_faults=faults, world=world.value,
                              can=can_settings(interface, channel, bitrate, data_bitrate))
    if json_out:
        print_json(summary)
    else:
        with_arm = " with the arm's joints and tool pose" if summary["arm"] else ""
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s){with_arm} to {out}")


@top_level.command("convert")
def convert(
    recording: Annotated[Path, typer.Argument(help="RealSense SDK recording (.bag, .db3), ROS 2 bag of "
                                                   "realsense-ros topics (.db3, .mcap or the bag folder), or a TUM "
                                                   "RGB-D or Open3D folder (docs/recording-format.md).")],
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    depth_scale: Annotated[float | None, typer.Option(callback=above(0.0), show_default=False, help=(
        "Depth unit of the frames directory, in metres \\[default: the recording's, at most 0.001: a D405's 0.1 mm "
        "steps are kept].")) ] = None,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Convert a RealSense, ROS 2, TUM RGB-D or Open3D recording into a frames directory, depth aligned to colour
    (streams that already share one pixel grid keep every depth pixel).

    Example: deploy convert session.db3 --out runs/session
    Example: deploy convert rosbag2_2026_01_01 --out runs/ros
    Example: deploy convert rgbd_dataset_freiburg1_xyz --out runs/fr1-xyz
    """
    from deploy.output_folder import new_output
    from drivers.camera.realsense_convert import convert_recording
    from drivers.camera.rgbd_folders import convert_folder, folder_kind

    converter = convert_folder if folder_kind(recording) else convert_recording
    with (new_output(out, overwrite, "recording", inputs=[recording]),
          progress_bar(f"converting {recording.name}") as bar):
        summary = converter(recording, out, depth_scale, progress=bar.advance)
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames ({summary['seconds']:.2f} s) to {out} (depth unit "
                      f"{summary['depth_scale']:g} m; the source's {summary['source_depth_scale']:g} m)")
        if summary["depth_out_of_range_px"]:
            console.print(f"{summary['depth_out_of_range_px']} depth pixels lay beyond what 16 bits of "
                          f"{summary['depth_scale']:g} m hold and were stored as no depth: pass a larger "
                          "--depth-scale to keep them")
        unpaired, listed = summary.get("unpaired_frames") or {}, summary.get("source_frames") or {}
        if any(unpaired.values()):
            known = None not in (listed.get("color"), listed.get("depth"))
            console.print(f"{unpaired['color']} colour and {unpaired['depth']} depth frames had no partner in the "
                          "other stream and were left out" + (f" (the file holds {listed['color']} colour and "
                                                              f"{listed['depth']} depth frames)" if known else ""))


class ExportFormat(str, Enum):
    tum = "tum"
    open3d = "open3d"
    rrd = "rrd"
    lerobot = "lerobot"


@top_level.command("export")
def export_cmd(
    recording: Annotated[Path, typer.Argument(help="Frames directory or run folder (docs/recording-format.md).")],
    out: Annotated[Path, typer.Option(help="Folder to write (tum, open3d, lerobot) or NAME.rrd (rrd).")],
    fmt: Annotated[ExportFormat, typer.Option("--format", help="tum: TUM RGB-D layout (rgb/, depth/, rgb.txt, "
                                              "depth.txt, groundtruth.txt with poses); open3d: Open3D's "
                                              "reconstruction layout with camera_intrinsic.json; rrd: a rerun "
                                              "recording (the robot from its URDF with the joints); lerobot: a "
                                              "LeRobot dataset (v3.0: parquet, mp4).")] = ExportFormat.tum,
    robot: Annotated[str | None, typer.Option("--robot", metavar="NAME|FILE", help="rrd: the robot config whose URDF "
                                              "shows the recorded joints \\[default: the one the recording names]."
                                              )] = None,
    fps: Annotated[int | None, typer.Option(min=1, max=1000, help="lerobot: frames per second of the dataset "
                                            "\\[default: the recording's median rate].")] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an earlier export at --out (once the new "
                                            "one is complete); without it an existing one is refused.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Export a frames recording to the layout other tools load (docs/recording-format.md#export).

    Example: deploy export runs/rec1 --format tum --out runs/rec1-tum
    Example: deploy export runs/drawer-1 --format rrd --out runs/drawer-1.rrd && rerun runs/drawer-1.rrd
    Example: deploy export runs/drawer-1 --format lerobot --out datasets/drawer-1
    """
    from deploy.export import export_recording

    with progress_bar(f"exporting {recording.name}", None) as bar:
        summary = export_recording(recording, out, fmt.value, progress=bar.counts, overwrite=overwrite, robot=robot,
                                   fps=fps)
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {summary['frames']} frames to {out} ({fmt.value}: {', '.join(summary['files'])})")
        if summary["depth_out_of_range_px"]:
            console.print(f"{summary['depth_out_of_range_px']} depth pixels lay beyond the 16 bits of the {fmt.value} "
                          "format and were written as no depth (0)")
