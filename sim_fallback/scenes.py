"""The scenario a simulated command asks for: its world, task, seed and split, the part a user names, and in a
kitchen a PartNet-Mobility object (`--assets DIR [--object ID] [--scale real|native]`) as the target furniture.

Without `--object` the seed picks the object: the usable ones (those that load and have a part of the task's kind
within the robot's reach, in id order) cycled by seed, so seeds 0..N-1 visit each of N objects once. An object that
cannot be used is left out with one line saying why (`task_objects`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from drivers.arm.robots import PANDA_REACH, Reach
from sim_fallback.errors import SceneError
from sim_fallback.furniture import Furniture
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.scenario import WORLDS, Scenario, make_scenario
from sim_fallback.start import Condition


@dataclass(frozen=True)
class TaskObjects:
    """The objects of a folder for one task: `usable` ids in id order, and `problems`: id -> why it cannot be used
    (one line each)."""

    usable: tuple[str, ...]
    problems: dict[str, str]

    def for_seed(self, seed: int) -> str:
        """The object seed `seed` opens: the usable ones cycled by seed."""
        return self.usable[seed % len(self.usable)]


def task_objects(assets: Path, task: str, scale: str = "real", reach: Reach = PANDA_REACH,
                 opening: float = 0.0) -> TaskObjects:
    """Which objects of `assets` can serve `task` ("drawer" or "door") at `scale`: loaded, with a part of the task's
    kind that opens at least `opening` (m or rad) within an arm's `reach`. PartNetError when none can (naming each
    object's problem)."""
    from sim_fallback.kitchen_scenario import reach_problem
    from sim_fallback.partnet import PartNetError, list_objects

    usable, problems = [], {}
    for entry in list_objects(Path(assets), scale):  # type: ignore[arg-type]
        problem = entry.problem
        if problem is None and not any(p.kind == task for p in entry.furniture.parts):
            problem = (f"{entry.furniture.source}: no {task} (it has "
                       f"{', '.join(p.name for p in entry.furniture.parts)}); fix: choose another task or object")
        problem = problem or reach_problem(entry.furniture, task, reach, opening)  # type: ignore[arg-type]
        if problem is None:
            usable.append(entry.object_id)
        else:
            problems[entry.object_id] = problem
    if not usable:
        raise PartNetError(f"{assets}: no object has a {task} the robot can use: "
                           + "; ".join(problems.values()))
    return TaskObjects(tuple(usable), problems)


def load_object(assets: Path, object_id: str, scale: str = "real") -> Furniture:
    """Object `object_id` of the folder `assets` as furniture at `scale` (PartNetError: one line, the fix)."""
    from sim_fallback.partnet import find_object, load_partnet

    return load_partnet(find_object(Path(assets), object_id), scale=scale)  # type: ignore[arg-type]


def object_task(furniture: Furniture, part: str | None) -> str:
    """The task a command means on `furniture` when it names none: the kind of the part `part` names (its name or
    link), else drawer when the furniture has one, else door."""
    if part is not None:
        try:
            return furniture.part(part).kind
        except KeyError:
            pass
    return "drawer" if any(p.kind == "drawer" for p in furniture.parts) else "door"


def check_scene(world: str, assets: Path | None = None, object_id: str | None = None) -> None:
    """SceneError (one line) for a world that is not one, --object without --assets, or --assets outside a kitchen."""
    if world not in WORLDS:
        raise SceneError(f"--world {world!r} is not a world: use one of {', '.join(WORLDS)}")
    if assets is None and object_id is not None:
        raise SceneError(f"--object {object_id} needs --assets DIR: the folder of PartNet-Mobility objects it is in")
    if assets is not None and world != "kitchen":
        raise SceneError(f"--assets places PartNet-Mobility objects in a kitchen, not in the {world} world: drop "
                         f"--world {world} (the kitchen is the default)")


def scene_scenario(world: str, task: str | None, seed: int, split: str = "train", part: str | None = None,
                   assets: Path | None = None, object_id: str | None = None, scale: str = "real",
                   condition: Condition = "normal", reach: Reach = PANDA_REACH,
                   opening: float = 0.0) -> Scenario | KitchenScenario:
    """The scenario of `world` for `task` (None: the object's task, `object_task`; drawer without an object),
    deterministic from the arguments; with `assets` the target is the PartNet-Mobility object `object_id` (default:
    the seed's, `task_objects`) loaded at `scale`; the target's grip in the arm's `reach`; without `part`, the seed's
    part opens at least `opening` (m or rad: the task's target). SceneError /
    PartNetError (one line each) for what cannot be built: an unknown world, --object or --assets with the box world
    or without a folder, a part the furniture does not have or cannot reach."""
    check_scene(world, assets, object_id)
    if assets is None:
        return make_scenario(world, task or "drawer", seed, split, part=part, condition=condition,  # type: ignore
                             reach=reach, opening=opening)
    if object_id is None:
        object_id = task_objects(assets, task or "drawer", scale, reach, opening).for_seed(seed)
    furniture = load_object(assets, object_id, scale)
    return make_scenario("kitchen", task or object_task(furniture, part), seed, split, part=part,  # type: ignore
                         target=furniture, condition=condition, reach=reach, opening=opening)


def scenario_object(scenario: Scenario | KitchenScenario) -> str:
    """What the scenario's target furniture is, for reports: "partnet 45213", "procedural test 3 base drawers", or
    the box world's "box cabinet"."""
    if isinstance(scenario, KitchenScenario):
        return scenario.kitchen.target_furniture.furniture.source
    return "box cabinet"
