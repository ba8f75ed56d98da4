"""`deploy sim show|record`: render simulated scenes and record scripted openings."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from deploy.commands.options import (
    AssetsOpt,
    JsonOpt,
    ObjectOpt,
    PartOpt,
    ScaleChoice,
    ScaleOpt,
    Split,
    Task,
    WorldChoice,
    WorldOpt,
    above,
    overwrite_option,
)
from deploy.commands.output import console, err_console, print_json, progress_bar

app = typer.Typer(help="PyBullet simulation: render scenes and record scripted openings.", no_args_is_help=True)

TaskOpt = Annotated[Task | None, typer.Option(
    help="A drawer or a door \\[default: the kind of the part --part names on --object, else drawer; sim show: door "
    "for an object that serves doors only].")]
SeedOpt = Annotated[int, typer.Option(min=0, help="Scenario seed.")]
SplitOpt = Annotated[Split, typer.Option(help="Object family.")]
OverwriteOpt = overwrite_option("recording at --out")
PHASES = {"grasp": "grasping the handle", "open": "opening along the true axis", "hold": "holding"}


@app.command("show")
def sim_show(
    task: TaskOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    world: WorldOpt = WorldChoice.kitchen,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    out: Annotated[Path, typer.Option(help="PNG to write.")] = Path("scene.png"),
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing file at --out; without it an "
                                            "existing one is refused.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Render a simulated scene: colour, depth and segmentation side by side. With --assets, list the objects' parts
    (kind, link, range) and why any object cannot be used, and render the object in its kitchen.

    Example: deploy sim show --task door --seed 3 --out door.png
    Example: deploy sim show --assets partnet-mobility-dataset/ --object 45213 --part "top drawer" --json
    """
    from deploy.errors import RecordingError

    if out.suffix.lower() != ".png":
        raise RecordingError(f"--out {out}: the scene image is a PNG: give a file name ending in .png")
    if out.exists() and not (overwrite and out.is_file()):
        raise RecordingError(f"--out {out} already exists: pass --overwrite to replace it, or choose another --out"
                             if out.is_file() else f"--out {out} is a folder: give a file name ending in .png")
    from sim_fallback.scenes import scenario_object  # after the checks: the simulator prints pybullet's banner
    from sim_fallback.show import render_scene_png

    listing = _listing(assets, object_id, task, scale) if assets is not None else {}
    kind = task.value if task else _servable_kind(listing, object_id, part)
    with err_console.status(f"rendering the scene of seed {seed}"):
        _, scenario = render_scene_png(kind, seed, out, split=split.value, world=world.value,
                                       part=part, assets=assets, object_id=object_id, scale=scale.value)
    data = {"out": str(out), "task": scenario.task, "seed": seed, "split": split.value, "world": world.value,
            "furniture": scenario_object(scenario), "part": scenario.part, **listing}
    if json_out:
        print_json(data)
        return
    for entry in listing.get("objects", []):
        parts = ", ".join(f"{p['name']} ({p['kind']}, {p['link']}, 0-{p['range'][1]:g} {p['unit']})"
                          for p in entry.get("parts", []))
        console.print(f"object {entry['id']} ({entry['category'] or 'no category'}): "
                      f"{entry['problem'] or parts}", soft_wrap=True)
        for kind, why in entry["unusable_for"].items():
            console.print(f"  not usable for a {kind}: {why}", soft_wrap=True)
    console.print(f"wrote {out}: {data['furniture']}, {data['part']} ({data['world']}, seed {seed})", soft_wrap=True)


def _servable_kind(listing: dict, object_id: str | None, part: str | None) -> str | None:
    """The task `sim show` renders --object for when none is given: "door" when the object cannot serve a drawer but
    can a door (its drawers behind its door, or out of reach), else None (the default)."""
    if object_id is None or part is not None or len(listing.get("objects", [])) != 1:
        return None
    unusable = listing["objects"][0]["unusable_for"]
    return "door" if "drawer" in unusable and "door" not in unusable else None


def _listing(assets: Path, object_id: str | None, task: Task | None, scale: ScaleChoice) -> dict:
    """`sim show --assets`: every object of the folder (or --object alone) with its parts, the one line that says
    why it does not load (`problem`) and, per task (--task, else both), why it cannot serve it (`unusable_for`)."""
    from sim_fallback.partnet import PartNetError, find_object, list_objects
    from sim_fallback.scenes import task_objects

    folder = find_object(assets, object_id) if object_id is not None else assets
    objects = [entry.describe() for entry in list_objects(folder, scale.value)]
    for entry in objects:
        entry["unusable_for"] = {}
    for kind in [task.value] if task is not None else ["drawer", "door"]:
        try:
            problems = task_objects(folder, kind, scale.value).problems
        except PartNetError as exc:  # none can serve it: each object's reason is in the one line
            problems = {entry["id"]: str(exc) for entry in objects}
        for entry in objects:
            if entry["id"] in problems and entry["problem"] is None:
                entry["unusable_for"][kind] = problems[entry["id"]]
    return {"assets": str(assets), "scale": scale.value, "objects": objects}


@app.command("record")
def sim_record(
    out: Annotated[Path, typer.Option(help="Frames directory to write.")],
    task: TaskOpt = None,
    seed: SeedOpt = 0,
    split: SplitOpt = Split.train,
    world: WorldOpt = WorldChoice.kitchen,
    part: PartOpt = None,
    assets: AssetsOpt = None,
    object_id: ObjectOpt = None,
    scale: ScaleOpt = ScaleChoice.real,
    fps: Annotated[float, typer.Option(callback=above(0.0), max=60.0, help="Camera frames per second.")] = 10.0,
    overwrite: OverwriteOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Record a scripted opening (a data generator that uses ground truth, not the policy).

    Writes the frames-directory format with masks, poses and truth.json. A part that stays shut (its catch or
    friction outholds the scripted grip) is an error naming it; the frames are kept.
    Example: deploy sim record --task drawer --seed 1 --out runs/drawer1 && deploy axis estimate runs/drawer1
    Example: deploy sim record --assets partnet-mobility-dataset/ --object 45213 --part door --out runs/45213-door
    """
    from deploy.output_folder import new_output
    from sim_fallback.scenes import check_scene
    from sim_fallback.scripted import record_scripted

    check_scene(world.value, assets, object_id)
    label = f"sim record {task.value} (seed {seed})" if task else f"sim record (seed {seed})"
    with new_output(out, overwrite, "recording"), progress_bar(label) as bar:
        shown = {"phase": ""}

        def each(phase: str, frames: int) -> None:
            if phase != shown["phase"]:
                shown["phase"] = phase
                bar.describe(PHASES[phase])
            bar.counts(frames, None)

        summary = record_scripted(task.value if task else None, seed, out, split=split.value, fps=fps,
                                  progress=each, world=world.value, part=part, assets=assets, object_id=object_id,
                                  scale=scale.value)
    if json_out:
        unit, factor = ("m", 1.0) if summary.task == "drawer" else ("deg", math.degrees(1.0))
        print_json({"out": str(out), "task": summary.task, "seed": seed, "split": split.value,
                    "world": summary.world, "part": summary.part, "assets": None if assets is None else str(assets),
                    "object": object_id, "scale": scale.value if assets is not None else None,
                    "frames": summary.frames, f"opened_{unit}": summary.joint_end * factor,
                    f"target_{unit}": summary.target * factor, "sim_time_s": summary.sim_time_s,
                    "wall_time_s": summary.wall_time_s})
    else:
        console.print(f"wrote {out}: {summary}", soft_wrap=True)
