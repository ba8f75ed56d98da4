"""`deploy` commands for the perception area: `track`, `models check`, `bench perception`."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")]
DeviceOpt = Annotated[str, typer.Option(help="auto (cuda, then mps, then cpu), cuda, mps or cpu.")]
DetectorOpt = Annotated[str | None, typer.Option(
    help="Grounding DINO: local directory or cached repo id (default IDEA-Research/grounding-dino-tiny).")]
TrackerOpt = Annotated[str | None, typer.Option(
    help="SAM2/EdgeTAM video model: local directory or cached repo id (default facebook/sam2.1-hiera-tiny).")]


class SegmenterChoice(str, Enum):
    gdino_sam2 = "gdino-sam2"
    classical = "classical"


def track(
    recording: Annotated[Path, typer.Argument(help="Frames directory (docs/recording-format.md).")],
    prompt: Annotated[str, typer.Option(help="What to segment (Grounding DINO text prompt).")] = "cabinet",
    segmenter: Annotated[SegmenterChoice, typer.Option(help="Backend.")] = SegmenterChoice.gdino_sam2,
    box: Annotated[tuple[float, float, float, float] | None, typer.Option(
        help="First-frame box X0 Y0 X1 Y1 in pixels; skips detection (required by classical).")] = None,
    out: Annotated[Path | None, typer.Option(
        help="Write a copy of the recording with the masks here (default: into the recording).")] = None,
    handle_prompt: Annotated[str, typer.Option(help="Handle prompt; empty to not track the handle.")] = "handle",
    detector: DetectorOpt = None,
    tracker: TrackerOpt = None,
    device: DeviceOpt = "auto",
    json_out: JsonOpt = False,
) -> None:
    """Segment and track the object through a recording, writing masks (mask/ folder) and an overlay PNG strip.

    Examples:
      deploy track runs/rec --prompt cabinet --out runs/rec-masks
      deploy track runs/rec --segmenter classical --box 112 79 468 362 --out runs/rec-classical --json
    """
    from deploy.cli import _print_json, print_rows
    from deploy.perception import make_segmenter
    from deploy.perception.config import perception_config
    from deploy.perception.track_recording import track_recording
    from drivers.camera.frames_dir import FramesRecording

    FramesRecording(recording)  # a wrong path fails here, before any model loads
    config = perception_config(object_prompt=prompt, handle_prompt=handle_prompt or None, box=box,
                               detector=detector, tracker=tracker, device=device)
    data = track_recording(recording, make_segmenter(segmenter.value, config), prompt, out)
    if json_out:
        _print_json(data)
        return
    print_rows(f"{data['segmenter']} on {recording}", data, digits=None)


def models_check(
    detector: DetectorOpt = None,
    tracker: TrackerOpt = None,
    device: DeviceOpt = "cpu",
    json_out: JsonOpt = False,
) -> None:
    """List each model (detector, tracker, EdgeTAM option), where it was looked for, whether it loads, and
    the command that fetches a missing one. Exits 1 when the detector or tracker in use does not load.

    Example: deploy models check --tracker ~/models/sam2.1-hiera-small --json
    """
    from deploy.cli import _print_json, console
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
        _print_json({"device": name, "models": rows})
    else:
        from rich.table import Table

        table = Table(title=f"models (loaded on {name})")
        for col in ("role", "model", "required", "where", "loads", "message"):
            table.add_column(col, overflow="fold")
        for r in rows:
            table.add_row(r["role"], r["source"], "yes" if r["required"] else "optional (EdgeTAM)", r["location"],
                          "[green]yes[/]" if r["loads"] else "[red]no[/]", r["message"])
        console.print(table)
    if not all(r["loads"] for r in rows if r["required"]):
        raise typer.Exit(1)


def bench_perception_cmd(
    seeds: Annotated[int, typer.Option(help="Scenario seeds (a drawer and a door recording each).")] = 1,
    fps: Annotated[float, typer.Option(help="Frames per second of the simulated recordings.")] = 10.0,
    json_out: JsonOpt = False,
) -> None:
    """Per-frame latency of each segmenter backend and its mask IoU against the simulator's oracle masks.

    gdino-sam2 / gdino-edgetam are measured only where their weights are in the local cache (else skipped).
    Example: deploy bench perception --seeds 2 --json
    """
    from rich.progress import Progress

    from deploy.cli import _print_json, console, err_console
    from deploy.perception.bench import bench_perception

    with Progress(console=err_console, transient=True) as bar:
        job = bar.add_task("bench perception", total=None)
        data = bench_perception(seeds, fps, progress=lambda what: bar.update(job, description=what))
    if json_out:
        _print_json(data)
        return
    from rich.table import Table

    table = Table(title=f"segmenters on {data['recordings']} simulated recordings ({data['device']})")
    for col in ("backend", "track ms median", "track ms p90", "start ms", "IoU median", "IoU min", "frames"):
        table.add_column(col)
    for name, r in data["backends"].items():
        if "skipped" in r:
            table.add_row(name, f"skipped: {r['skipped']}", "", "", "", "", "0")
            continue
        table.add_row(name, f"{r['latency_ms_median']:.1f}", f"{r['latency_ms_p90']:.1f}",
                      f"{r['start_ms_median']:.0f}", f"{r['iou_median']:.3f}", f"{r['iou_min']:.3f}", str(r["frames"]))
    console.print(table)


def register(app: typer.Typer, bench_app: typer.Typer) -> None:
    """Add this area's commands to the main app and to `deploy bench`."""
    app.command("track")(track)
    models_app = typer.Typer(help="Model weights: what is present, where, and how to fetch the rest.",
                             no_args_is_help=True)
    models_app.command("check")(models_check)
    app.add_typer(models_app, name="models")
    bench_app.command("perception")(bench_perception_cmd)
