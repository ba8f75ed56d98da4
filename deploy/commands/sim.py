"""`deploy sim show|record`: render simulated scenes and record scripted openings."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import JsonOpt, Split, Task, above, overwrite_option
from deploy.commands.output import console, err_console, print_json, progress_bar

app = typer.Typer(help="PyBullet simulation: render scenes and record scripted openings.", no_args_is_help=True)

TaskOpt = Annotated[Task, typer.Option(help="Cabinet with a drawer or a door.")]
SeedOpt = Annotated[int, typer.Option(min=0, help="Scenario seed.")]
SplitOpt = Annotated[Split, typer.Option(help="Object family.")]
OverwriteOpt = overwrite_option("recording at --out")
PHASES = {"grasp": "grasping the handle", "open": "opening along the true axis", "hold": "holding"}


@app.command("show")
def sim_show(
    task: TaskOpt = Task.drawer,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("scene.png"),
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing file at --out; without it an "
                                            "existing one is refused.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Render a simulated scene: colour, depth and segmentation side by side.

    Example: deploy sim show --task door --seed 3 --out door.png
    """
    from deploy.errors import RecordingError

    if out.suffix.lower() != ".png":
        raise RecordingError(f"--out {out}: the scene image is a PNG: give a file name ending in .png")
    if out.exists() and not (overwrite and out.is_file()):
        raise RecordingError(f"--out {out} already exists: pass --overwrite to replace it, or choose another --out"
                             if out.is_file() else f"--out {out} is a folder: give a file name ending in .png")
    from sim_fallback.show import render_scene_png  # after the checks: it prints pybullet's banner

    with err_console.status(f"rendering the {task.value} scene of seed {seed}"):
        render_scene_png(task.value, seed, out, split=split.value)
    if json_out:
        print_json({"out": str(out), "task": task.value, "seed": seed, "split": split.value})
    else:
        console.print(f"wrote {out}")


@app.command("record")
def sim_record(
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    task: TaskOpt = Task.drawer,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    fps: Annotated[float, typer.Option(callback=above(0.0), max=60.0, help="Camera frames per second.")] = 10.0,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Record a scripted opening (a data generator that uses ground truth, not the policy).

    Writes the frames-directory format with masks, poses and truth.json.
    Example: deploy sim record --task drawer --seed 1 --out runs/drawer1 && deploy axis estimate runs/drawer1
    """
    from deploy.output_folder import new_output
    from sim_fallback.scripted import record_scripted

    with new_output(out, overwrite, "recording"), progress_bar(f"sim record {task.value} (seed {seed})") as bar:
        shown = {"phase": ""}

        def each(phase: str, frames: int) -> None:
            if phase != shown["phase"]:
                shown["phase"] = phase
                bar.describe(PHASES[phase])
            bar.counts(frames, None)

        summary = record_scripted(task.value, seed, out, split=split.value, fps=fps, progress=each)
    if json_out:
        unit, scale = ("m", 1.0) if task is Task.drawer else ("deg", math.degrees(1.0))
        print_json({"out": str(out), "task": task.value, "seed": seed, "split": split.value,
                    "frames": summary.frames, f"opened_{unit}": summary.joint_end * scale,
                    f"target_{unit}": summary.target * scale, "sim_time_s": summary.sim_time_s,
                    "wall_time_s": summary.wall_time_s})
    else:
        console.print(f"wrote {out}: {summary}", soft_wrap=True)
