"""`deploy track` and `deploy models check`: segment and track recordings, and check the model weights."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import JsonOpt, kind_option, view_option
from deploy.commands.output import print_json, print_rows, print_table, progress_bar, view_file
from deploy.perception.registry import SEGMENTERS

top_level = typer.Typer()  # its commands sit directly under `deploy`
models_app = typer.Typer(help="Model weights: what is present, where, and how to fetch the rest.", no_args_is_help=True)

DeviceOpt = Annotated[str, typer.Option(help="auto (cuda, then mps, then cpu), cuda, mps or cpu.")]
DetectorOpt = Annotated[str | None, typer.Option(
    help="Grounding DINO: local directory or cached repo id (default IDEA-Research/grounding-dino-tiny).")]
TrackerOpt = Annotated[str | None, typer.Option(
    help="SAM2/EdgeTAM video model: local directory or cached repo id (default facebook/sam2.1-hiera-tiny).")]


TrackSegmenterOpt = kind_option(SEGMENTERS, "--segmenter", " Backend.")
TrackOverwriteOpt = Annotated[bool, typer.Option("--overwrite", help="Replace an existing recording at --out (all "
                                                  "its old files are removed) and an existing --rrd file; without it "
                                                  "an existing one is refused.")]
ViewOpt = view_option("the frames and the masks found (saved to --rrd)")


@top_level.command("track")
def track(
    recording: Annotated[Path, typer.Argument(help="Frames directory (docs/recording-format.md).")],
    prompt: Annotated[str, typer.Option(help="What to segment (Grounding DINO text prompt).")] = "cabinet",
    segmenter: TrackSegmenterOpt = "gdino-sam2",
    box: Annotated[tuple[float, float, float, float] | None, typer.Option(
        "--box", metavar="X0 Y0 X1 Y1", help="First-frame box in pixels; skips detection (required by "
        "classical).")] = None,
    out: Annotated[Path | None, typer.Option(
        help="Write a copy of the recording with the masks here (default: into the recording).")] = None,
    handle_prompt: Annotated[str, typer.Option(help="Handle prompt; empty to not track the handle.")] = "handle",
    detector: DetectorOpt = None,
    tracker: TrackerOpt = None,
    device: DeviceOpt = "auto",
    view: ViewOpt = False,
    rrd: Annotated[Path | None, typer.Option(
        "--rrd", metavar="PATH", help="Where --view saves the rerun file (implies --view) \\[default: OUT/track.rrd "
        "with --out, else runs/REC-track.rrd (REC-track-2.rrd, ... when taken): never inside the input "
        "recording].")] = None,
    overwrite: TrackOverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Segment and track the object through a recording, writing masks (mask/ folder) and an overlay PNG strip.

    Examples:
      deploy track runs/rec --prompt cabinet --out runs/rec-masks
      deploy track runs/rec --segmenter classical --box 112 79 468 362 --out runs/rec-classical --json
    """
    from contextlib import nullcontext

    from deploy.output_folder import new_output
    from deploy.perception.config import perception_config
    from deploy.perception.registry import make_segmenter
    from deploy.perception.track_recording import copy_target, track_recording
    from drivers.camera.frames_dir import FramesRecording

    copy_target(recording, out, FramesRecording(recording))  # a wrong path or --out fails here, before any model loads
    copy = out is not None and out.resolve() != recording.resolve()
    viewer, rrd_path = None, None
    if view or rrd is not None:  # checked now, opened once the output folder is the new one
        rrd_path = out / "track.rrd" if rrd is None and out is not None else view_file(recording, rrd, "track",
                                                                                        overwrite)
    with new_output(out, overwrite, "recording", inputs=[recording]) if copy else nullcontext():
        config = perception_config(object_prompt=prompt, handle_prompt=handle_prompt or None, box=box,
                                   detector=detector, tracker=tracker, device=device)
        backend = make_segmenter(segmenter, config)
        if rrd_path is not None:
            from deploy.report.viewer import RerunViewer

            viewer = RerunViewer(rrd_path)
        with progress_bar(f"tracking {recording.name}") as bar:
            data = track_recording(recording, backend, prompt, out, progress=bar.counts, viewer=viewer)
    if viewer is not None:
        data["rrd"] = str(viewer.path)
    if json_out:
        print_json(data)
        return
    print_rows(f"{data['segmenter']} on {recording}", data, digits=None)


@models_app.command("check")
def models_check(
    detector: DetectorOpt = None,
    tracker: TrackerOpt = None,
    device: DeviceOpt = "auto",
    json_out: JsonOpt = False,
) -> None:
    """List each model (detector, tracker, EdgeTAM option), where it was looked for, whether it loads, and
    the command that fetches a missing one. Exits 1 when the detector or tracker in use does not load.

    Example: deploy models check --tracker ~/models/sam2.1-hiera-small --json
    """
    from deploy.perception.config import EDGETAM_TRACKER, perception_config
    from deploy.perception.device import choose_device
    from deploy.perception.models import check_models

    config = perception_config(detector=detector, tracker=tracker, device=device)
    name, _ = choose_device(config.device)
    wanted = [("detector", config.detector), ("tracker", config.tracker)]
    if EDGETAM_TRACKER != config.tracker:
        wanted.append(("tracker", EDGETAM_TRACKER))
    statuses = check_models(wanted, name)
    rows = [dict(s.to_dict(), required=i < 2) for i, s in enumerate(statuses)]
    if json_out:
        print_json({"device": name, "models": rows})
    else:
        print_table(f"models (loaded on {name})", ("role", "model", "required", "where", "loads", "message"),
                    [(r["role"], r["source"], "yes" if r["required"] else "optional (EdgeTAM)", r["location"],
                      "[green]yes[/]" if r["loads"] else "[red]no[/]", r["message"]) for r in rows], overflow="fold")
    if not all(r["loads"] for r in rows if r["required"]):
        raise typer.Exit(1)

