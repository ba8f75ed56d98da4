"""`deploy sim show|record`: render simulated scenes and record scripted openings."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import Split, Task
from deploy.commands.output import console

app = typer.Typer(help="PyBullet simulation: render scenes and record scripted openings.", no_args_is_help=True)

TaskOpt = Annotated[Task, typer.Option(help="Cabinet with a drawer or a door.")]
SeedOpt = Annotated[int, typer.Option(help="Scenario seed.")]
SplitOpt = Annotated[Split, typer.Option(help="Object family.")]


@app.command("show")
def sim_show(
    task: TaskOpt = Task.drawer,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("scene.png"),
) -> None:
    """Render a simulated scene: colour, depth and segmentation side by side.

    Example: deploy sim show --task door --seed 3 --out door.png
    """
    from sim_fallback.show import render_scene_png

    render_scene_png(task.value, seed, out, split=split.value)
    console.print(f"wrote {out}")


@app.command("record")
def sim_record(
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    task: TaskOpt = Task.drawer,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    fps: Annotated[float, typer.Option(help="Camera frames per second.")] = 10.0,
) -> None:
    """Record a scripted opening (a data generator that uses ground truth, not the policy).

    Writes the frames-directory format with masks, poses and truth.json.
    Example: deploy sim record --task drawer --seed 1 --out runs/drawer1 && deploy axis estimate runs/drawer1
    """
    from sim_fallback.scripted import record_scripted

    summary = record_scripted(task.value, seed, out, split=split.value, fps=fps)
    console.print(f"wrote {out}: {summary}")
