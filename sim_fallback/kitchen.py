"""Seeded kitchens around a target piece of furniture, in the room's frame: x out of the back wall's face, y along
it, z up from the floor; metres.

Every kitchen has a floor and a back wall. Base units stand in a run against the wall, touching each other, with the
same finishes and their own fronts and handles, under a countertop that overhangs their fronts; a tall unit may end
the run (packed out from the wall when shallower than it: a fitted kitchen's fronts line up) and a side wall close
it; wall units may hang above the counter; a free-standing chest or cupboard may stand further along the wall; boxes
and cylinders stand on the counter and on the floor.

The target (a procedural unit or any `Furniture`, e.g. a PartNet-Mobility model) takes its place by its size: up to
TALL_FROM_M high and no deeper than MAX_RUN_DEPTH_M it stands in the run, which takes its height and depth; taller,
it ends the run as a tall unit; lower than MIN_RUN_HEIGHT_M and small enough for the counter (an appliance, a box
with drawers) it stands on the countertop, its front near the counter's edge; otherwise it stands free against the
wall beside the run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim_fallback.furniture import Finish, Furniture
from sim_fallback.layout import Placed, StaticShape
from sim_fallback.unit_families import (
    LAYOUTS,
    Carcass,
    Look,
    Role,
    Split,
    lowest_run_height,
    random_carcass,
    random_finish,
    random_look,
    random_unit,
    random_width,
)

TALL_FROM_M = 1.2  # a target at least this high stands at the end of the run as a tall unit
MIN_RUN_HEIGHT_M = 0.5  # ... lower than this it stands free
MAX_RUN_DEPTH_M = 0.8
ON_COUNTER_M = (0.55, 0.9)  # a low target no deeper and no wider than this stands on the counter (depth, width)
COUNTER_EDGE_M = 0.03  # ... its front this far back from the counter's edge
WALL_HEIGHT_M = (2.4, 2.7)
COUNTER_M = (0.03, 0.045)  # countertop thickness
OVERHANG_M = (0.02, 0.04)  # over the fronts
WALL_UNIT_GAP_M = (0.50, 0.60)  # counter top to a wall unit's bottom
FREE_GAP_M = (0.4, 0.9)  # run end to a free-standing piece
FLOOR_BEYOND_M = 1.5  # the floor and back wall reach this far beyond the furniture
ROOM_DEPTH_M = 3.0
FLOOR_OBJECT_AWAY_M = 1.1  # floor objects stand at least this far along the wall from the target's centre
SHELL_M = 0.1  # wall thickness
FILLER_M = 0.03  # a side wall stands this far beyond the run's end: the filler strip fitters leave so that the doors
# and handles beside a wall open (models' doors may also reach a little past their body's box)


@dataclass
class Room:
    """A kitchen being built: placed furniture and static shapes in the room frame, and the index of the target."""

    furniture: list[Placed] = field(default_factory=list)
    statics: list[StaticShape] = field(default_factory=list)
    target: int = -1

    def add(self, furniture: Furniture, x: float, y: float, z: float = 0.0, yaw: float = 0.0,
            target: bool = False) -> None:
        if target:
            self.target = len(self.furniture)
        self.furniture.append(Placed(furniture, (x, y, z, yaw)))

    def shape(self, name: str, size, centre, finish: Finish, kind: str = "box") -> None:
        self.statics.append(StaticShape(name, kind, tuple(float(v) for v in size),  # type: ignore[arg-type]
                                        (float(centre[0]), float(centre[1]), float(centre[2]), 0.0), finish))

    def y_range(self) -> tuple[float, float]:
        ys = np.concatenate([p.footprint()[:, 1] for p in self.furniture])
        return float(ys.min()), float(ys.max())


def role_of(furniture: Furniture) -> Role:
    """Where a target stands by its size: in the run ("base"), ending it ("tall"), on the countertop ("counter") or
    on its own ("free")."""
    width, depth, height = furniture.size_m
    if height >= TALL_FROM_M:
        return "tall"
    if height < MIN_RUN_HEIGHT_M and depth <= ON_COUNTER_M[0] and width <= ON_COUNTER_M[1]:
        return "counter"
    return "base" if height >= MIN_RUN_HEIGHT_M and depth <= MAX_RUN_DEPTH_M else "free"


def standing_height(furniture: Furniture) -> float:
    """The lowest a target stands above the floor (m): on it, or on the lowest countertop for a "counter" target."""
    return lowest_run_height() + COUNTER_M[0] if role_of(furniture) == "counter" else 0.0


def random_target(task: str, split: Split, look: Look, rng: np.random.Generator, source: str) -> tuple[Role, Furniture]:
    """A procedural target unit with at least one part of the task's kind: its role and the unit."""
    roles: list[Role] = ["base", "tall", "free"] + (["wall"] if task == "door" else [])
    weights = [0.55, 0.15, 0.15, 0.15] if task == "door" else [0.6, 0.15, 0.25]
    role: Role = roles[int(rng.choice(len(roles), p=weights))]
    layouts = [lay for lay in LAYOUTS[role] if task == "door" or lay not in ("door", "doors")]
    if task == "door":
        layouts = [lay for lay in layouts if lay not in ("drawers", "chest")]
    layout = str(rng.choice(layouts))
    unit = random_unit(role, layout, random_width(split, layout, rng), random_carcass(split, role, rng), look, split,
                       rng, f"{source} {role} {layout}")
    return role, unit.furniture()


def random_room(target: Furniture, role: Role, split: Split, look: Look, rng: np.random.Generator,
                source: str) -> Room:
    """A kitchen around `target` standing in `role` (a wall unit hangs above the counter)."""
    room = Room()
    run = random_carcass(split, "base", rng)
    if role == "base":
        _, depth, height = target.size_m
        run = Carcass(depth, height, run.plinth_m, run.wall_m, run.front_m)
    counter_top = _base_run(room, target if role == "base" else None, run, look, split, rng, source)
    ends = room.y_range()
    if role == "counter":
        _on_counter(room, target, counter_top, ends, rng)
    tall_end = float(rng.choice([-1.0, 1.0]))
    if role == "tall" or rng.random() < 0.6:
        tall = target if role == "tall" else random_unit(
            "tall", str(rng.choice(LAYOUTS["tall"])), random_width(split, "single", rng),
            random_carcass(split, "tall", rng), look, split, rng, f"{source} tall unit").furniture()
        width, depth, _ = tall.size_m
        y = ends[1] + width / 2 if tall_end > 0 else ends[0] - width / 2
        x = max(depth, run.depth_m) - depth / 2  # a tall unit shallower than the run is packed out from the wall,
        # its front level with the run's (a fitted kitchen's fronts line up): the run's fronts and counter would
        # otherwise stand out beside its door's edge, boxing in a handle there
        room.add(tall, x, y, target=role == "tall")
    all_ends = room.y_range()
    closed = all_ends[1] if tall_end > 0 else all_ends[0]  # the end (past a tall unit) a side wall may stand beyond
    if role == "wall" or rng.random() < 0.7:
        _wall_run(room, target if role == "wall" else None, ends, counter_top, tall_end, split, look, rng, source)
    all_ends = room.y_range()
    side_wall = rng.random() < 0.5
    if role == "free" or rng.random() < 0.5:
        free = target if role == "free" else _free_unit(split, rng, source)
        width, depth, _ = free.size_m
        gap = float(rng.uniform(*FREE_GAP_M))
        y = all_ends[0] - gap - width / 2 if tall_end > 0 else all_ends[1] + gap + width / 2
        room.add(free, depth / 2 + float(rng.uniform(0.0, 0.05)), y, target=role == "free")
    _counter_objects(room, counter_top, run.depth_m, ends, rng, role == "counter")
    _floor_objects(room, rng)
    _shell(room, tall_end, closed if side_wall else None, rng)
    return room


def _base_run(room: Room, target: Furniture | None, run: Carcass, look: Look, split: Split,
              rng: np.random.Generator, source: str) -> float:
    """The run of base units (with the target among them when given) and its countertop; the counter's top height."""
    left, right = int(rng.integers(0, 4)), int(rng.integers(0, 4))
    right = max(right, (1 if target is not None else 2) - left)  # a run of two units at least
    units: list[tuple[Furniture, bool]] = []
    for k in range(left + right):
        layout = str(rng.choice(LAYOUTS["base"]))
        unit = random_unit("base", layout, random_width(split, layout, rng), run, look, split, rng,
                           f"{source} base unit {k}")
        units.append((unit.furniture(), False))
    if target is not None:
        units.insert(left, (target, True))
    y = 0.0
    for furniture, is_target in units:
        width, depth, _ = furniture.size_m
        room.add(furniture, depth / 2, y + width / 2, target=is_target)
        y += width
    thickness, overhang = float(rng.uniform(*COUNTER_M)), float(rng.uniform(*OVERHANG_M))
    finish = random_finish("laminate" if rng.random() < 0.6 else "wood", rng)
    depth = max(f.size_m[1] for f, _ in units) + overhang
    # the counter ends with the run: it butts against a tall unit's side rather than entering it
    room.shape("countertop", (depth, y, thickness), (depth / 2, y / 2, run.height_m + thickness / 2), finish)
    return run.height_m + thickness


def _wall_run(room: Room, target: Furniture | None, ends: tuple[float, float], counter_top: float, tall_end: float,
              split: Split, look: Look, rng: np.random.Generator, source: str) -> None:
    """Wall units hung above the counter from one end of the base run (the target among them when given)."""
    carcass = random_carcass(split, "wall", rng)
    units = []
    for k in range(int(rng.integers(1, 4))):
        layout = str(rng.choice(LAYOUTS["wall"]))
        units.append((random_unit("wall", layout, random_width(split, layout, rng), carcass, look, split, rng,
                                  f"{source} wall unit {k}").furniture(), False))
    if target is not None:
        units.insert(int(rng.integers(0, len(units) + 1)), (target, True))
    z = counter_top + float(rng.uniform(*WALL_UNIT_GAP_M))
    y = ends[0] if tall_end > 0 else ends[1] - sum(f.size_m[0] for f, _ in units)
    pending = target is not None  # the target is still to hang: a unit that does not fit before it is left out
    for furniture, is_target in units:
        width, depth, _ = furniture.size_m
        if y + width > ends[1] + 1e-9 and not is_target:
            if pending:
                continue
            break
        room.add(furniture, depth / 2, y + width / 2, z, target=is_target)
        pending = pending and not is_target
        y += width


def _free_unit(split: Split, rng: np.random.Generator, source: str) -> Furniture:
    """A free-standing chest or cupboard with its own look."""
    layout = str(rng.choice(LAYOUTS["free"]))
    return random_unit("free", layout, random_width(split, layout, rng), random_carcass(split, "free", rng),
                       random_look(split, rng), split, rng, f"{source} free {layout}").furniture()


def _on_counter(room: Room, target: Furniture, counter_top: float, ends: tuple[float, float],
                rng: np.random.Generator) -> None:
    """The target on the countertop, somewhere along the run, its front COUNTER_EDGE_M back from the edge."""
    width, depth, _ = target.size_m
    counter = next(s for s in room.statics if s.name == "countertop")
    edge = counter.pose[0] + counter.size[0] / 2
    y = float(rng.uniform(ends[0] + width / 2, max(ends[1] - width / 2, ends[0] + width / 2)))
    room.add(target, edge - COUNTER_EDGE_M - depth / 2, y, counter_top, target=True)


def _counter_objects(room: Room, counter_top: float, depth: float, ends: tuple[float, float],
                     rng: np.random.Generator, target_on_it: bool = False) -> None:
    """Boxes and cylinders on the counter, toward its back, apart from each other (and from the target on it)."""
    taken: list[tuple[float, float]] = []
    if target_on_it:
        placed = room.furniture[room.target]
        taken.append((placed.pose[1], placed.furniture.size_m[0] / 2 + 0.05))
    for _ in range(int(rng.integers(2, 6))):
        cylinder = rng.random() < 0.5
        size = (np.repeat(rng.uniform(0.06, 0.16), 2) if cylinder else rng.uniform(0.06, 0.22, 2))
        height = float(rng.uniform(0.08, 0.32))
        y = float(rng.uniform(ends[0] + size[1], ends[1] - size[1]))
        crowded = any(abs(y - other) < (half + size[1] / 2 + 0.02) for other, half in taken)
        if ends[1] - ends[0] < 2 * size[1] or crowded:
            continue
        taken.append((y, size[1] / 2))
        x = float(rng.uniform(0.05 + size[0] / 2, max(depth - 0.15 - size[0] / 2, 0.06 + size[0] / 2)))
        room.shape("object", (*size, height), (x, y, counter_top + height / 2),
                   random_finish(str(rng.choice(["painted", "metal", "wood"])), rng),  # type: ignore[arg-type]
                   "cylinder" if cylinder else "box")


def _floor_objects(room: Room, rng: np.random.Generator) -> None:
    """A bin, a crate or a box on the floor in front of the furniture or the wall, away from the target's front."""
    target_y = room.furniture[room.target].pose[1]
    y0, y1 = room.y_range()
    wanted, taken = int(rng.integers(1, 4)), []
    for _ in range(12):
        if len(taken) == wanted:
            return
        cylinder = rng.random() < 0.5
        size = np.repeat(rng.uniform(0.25, 0.4), 2) if cylinder else rng.uniform(0.2, 0.5, 2)
        height = float(rng.uniform(0.2, 0.55))
        y = float(rng.uniform(y0 - 1.0, y1 + 1.0))
        if abs(y - target_y) < FLOOR_OBJECT_AWAY_M + size[1] / 2 or any(abs(y - t) < 0.5 for t in taken):
            continue
        band = [p.footprint()[:, 0].max() for p in room.furniture
                if p.pose[2] < height and abs(p.pose[1] - y) < (p.furniture.size_m[0] + size[1]) / 2]
        x = max(band, default=0.0) + 0.03 + size[0] / 2 + float(rng.uniform(0.0, 0.25))
        room.shape("object", (*size, height), (x, y, height / 2),
                   random_finish(str(rng.choice(["painted", "metal", "wood"])), rng),  # type: ignore[arg-type]
                   "cylinder" if cylinder else "box")
        taken.append(y)


def _shell(room: Room, tall_end: float, side_wall_at: float | None, rng: np.random.Generator) -> None:
    """Floor and back wall beyond the furniture, and a side wall at `side_wall_at` (y) when given."""
    y0, y1 = room.y_range()
    y0, y1 = y0 - FLOOR_BEYOND_M, y1 + FLOOR_BEYOND_M
    height = float(rng.uniform(*WALL_HEIGHT_M))
    wall = random_finish("painted", rng, light=True)
    floor = random_finish("wood" if rng.random() < 0.5 else "laminate", rng)
    room.statics.insert(0, StaticShape("floor", "box", (ROOM_DEPTH_M + SHELL_M, y1 - y0, 0.02),
                                       ((ROOM_DEPTH_M - SHELL_M) / 2, (y0 + y1) / 2, -0.01, 0.0), floor))
    room.shape("wall", (SHELL_M, y1 - y0, height), (-SHELL_M / 2, (y0 + y1) / 2, height / 2), wall)
    if side_wall_at is not None:
        y = side_wall_at + tall_end * (FILLER_M + SHELL_M / 2)
        room.shape("wall", (ROOM_DEPTH_M, SHELL_M, height), (ROOM_DEPTH_M / 2, y, height / 2), wall)
