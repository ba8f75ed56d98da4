"""The families of procedural units: sizes, layouts of fronts and looks, drawn from a seeded generator.

Two disjoint families like the paper's train and test objects: every size interval of one split is disjoint from the
other's, and the test family has handle styles the train family lacks (sim_fallback/handles.py). A kitchen draws all
of its units from one family.

Roles: "base" (in a run under a countertop), "tall" (floor to above head height), "wall" (hung above the counter),
"free" (a free-standing chest or cupboard). Layouts per role are in LAYOUTS.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from sim_fallback.furniture import Finish, FinishKind, Mechanism, PartKind
from sim_fallback.handles import STYLES, HandleSpec, random_handle
from sim_fallback.mechanisms import random_mechanism
from sim_fallback.units import TRAY_CLEARANCE_M, FrontSpec, HandlePlace, UnitSpec, handle_position

Split = Literal["train", "test"]
Role = Literal["base", "tall", "wall", "free", "counter"]  # "counter": a given target only
LAYOUTS: dict[str, tuple[str, ...]] = {
    "base": ("drawers", "door", "doors", "drawer-over-door", "drawer-over-doors"),
    "tall": ("doors", "drawers-door"), "wall": ("door", "doors"), "free": ("chest", "cupboard")}
# (low, high) per split; the train and test intervals of every size are disjoint
_SIZES: dict[str, dict[str, tuple[float, float]]] = {
    "train": {"single": (0.40, 0.52), "double": (0.66, 0.78), "depth": (0.55, 0.59), "height": (0.80, 0.86),
              "plinth": (0.08, 0.11), "wall_depth": (0.30, 0.33), "wall_height": (0.60, 0.70),
              "tall_height": (1.95, 2.05), "free_depth": (0.40, 0.46), "free_height": (0.80, 0.90),
              "wall_m": (0.016, 0.018), "front_m": (0.018, 0.019)},
    "test": {"single": (0.53, 0.64), "double": (0.80, 0.92), "depth": (0.60, 0.64), "height": (0.87, 0.92),
             "plinth": (0.12, 0.15), "wall_depth": (0.34, 0.37), "wall_height": (0.72, 0.80),
             "tall_height": (2.06, 2.20), "free_depth": (0.47, 0.52), "free_height": (0.91, 1.05),
             "wall_m": (0.0185, 0.020), "front_m": (0.0195, 0.022)},
}
_DRAWER_PROFILES = {2: (0.5, 0.5), 3: (0.24, 0.33, 0.43), 4: (0.19, 0.23, 0.27, 0.31), 5: (0.2,) * 5}
_ORDINALS = ("top", "second", "third", "fourth", "fifth")
RAIL_M = 0.035  # with edge pulls the fronts stop this far below the top: room to reach over a top edge's pull
DRAWER_STOP_M = 0.02  # a drawer's end stop: this much of its tray stays inside the carcass
VERTICAL_ON_DOORS = ("bar", "long-bar", "recessed")
_FRONT_KINDS: tuple[FinishKind, ...] = ("wood", "laminate", "painted")


@dataclass(frozen=True)
class Look:
    """What a kitchen's units share: carcass, front and handle finishes, and the handle (horizontal on drawers;
    on doors a bar or a recessed pull stands vertical, knobs, cups and edge pulls stay as they are)."""

    body: Finish
    front: Finish
    handle_finish: Finish
    handle: HandleSpec

    def handle_for(self, kind: PartKind) -> HandleSpec:
        return replace(self.handle, vertical=kind == "door" and self.handle.style in VERTICAL_ON_DOORS)


def random_finish(kind: FinishKind, rng: np.random.Generator, light: bool = False) -> Finish:
    """A finish of `kind` with a plausible colour and gloss; `light`: a pale colour, as most walls are."""
    if kind == "wood":
        rgb = rng.uniform([0.45, 0.28, 0.13], [0.78, 0.52, 0.30])
    elif kind == "laminate":
        grey = rng.uniform(0.15, 0.95)
        rgb = np.clip(grey + rng.uniform(-0.04, 0.04, 3), 0, 1)
    elif kind == "metal":
        rgb = [(0.65, 0.66, 0.68), (0.08, 0.08, 0.09), (0.72, 0.56, 0.28)][int(rng.integers(3))]
    else:
        rgb = rng.uniform(0.2, 0.92, 3) if not light else rng.uniform(0.72, 0.95) + rng.uniform(-0.05, 0.05, 3)
    gloss = {"wood": (0.05, 0.3), "laminate": (0.1, 0.5), "painted": (0.05, 0.6), "metal": (0.5, 0.9)}[kind]
    return Finish(kind, tuple(round(float(c), 3) for c in rgb), float(rng.uniform(*gloss)),  # type: ignore[arg-type]
                  int(rng.integers(1 << 30)))


def random_look(split: Split, rng: np.random.Generator, style: str | None = None) -> Look:
    """A kitchen's look from the `split` family; `style` forces the handle style (else drawn from the family's)."""
    front = random_finish(_FRONT_KINDS[int(rng.integers(3))], rng)
    body = front if rng.random() < 0.5 else random_finish("laminate", rng)
    handle_finish = random_finish("metal" if rng.random() < 0.8 else "painted", rng)
    style = style or str(rng.choice(STYLES[split]))
    return Look(body, front, handle_finish, random_handle(style, split, False, rng))


@dataclass(frozen=True)
class Carcass:
    """The sizes units of one run share (m): depth (fronts included), height (plinth included) and plinth; panel
    and front thicknesses."""

    depth_m: float
    height_m: float
    plinth_m: float
    wall_m: float
    front_m: float


def random_carcass(split: Split, role: Role, rng: np.random.Generator) -> Carcass:
    """The carcass sizes of a unit of `role` in the `split` family."""
    r = _SIZES[split]
    depth, height, plinth = (float(rng.uniform(*r[k])) for k in ("depth", "height", "plinth"))
    if role == "wall":
        depth, height, plinth = float(rng.uniform(*r["wall_depth"])), float(rng.uniform(*r["wall_height"])), 0.0
    elif role == "tall":
        height = float(rng.uniform(*r["tall_height"]))
    elif role == "free":
        depth, height = float(rng.uniform(*r["free_depth"])), float(rng.uniform(*r["free_height"]))
        plinth *= 0.6
    return Carcass(depth, height, plinth, float(rng.uniform(*r["wall_m"])), float(rng.uniform(*r["front_m"])))


def lowest_run_height() -> float:
    """The lowest base run of any family (m): where the countertop stands at the least."""
    return min(sizes["height"][0] for sizes in _SIZES.values())


def random_width(split: Split, layout: str, rng: np.random.Generator) -> float:
    wide = layout in ("doors", "drawer-over-doors", "chest", "cupboard")
    return float(rng.uniform(*_SIZES[split]["double" if wide else "single"]))


Row = tuple[float, float, list[tuple[PartKind, str, int, HandlePlace]]]  # z range, (kind, name, hinge, place)


def _rows(role: Role, layout: str, z0: float, z1: float, rng: np.random.Generator) -> list[Row]:
    """The unit's fronts as rows from the top: each a z range and its fronts left to right as seen facing it."""
    hinge = int(rng.choice([-1, 1]))
    place: HandlePlace = "bottom" if role == "wall" else "top"
    door: list = [("door", "door", hinge, place)]
    pair: list = [("door", "left door", -1, place), ("door", "right door", 1, place)]
    if role == "tall":
        split_z = z0 + float(rng.uniform(0.70, 0.80))  # its lower part as high as a base unit's fronts
        if layout == "doors":
            return [(split_z, z1, [("door", "upper door", hinge, "bottom")]),
                    (z0, split_z, [("door", "lower door", hinge, "top")])]
        return [(split_z, z1, [("door", "door", hinge, "bottom")]), *_drawer_rows(2, z0, split_z, rng)]
    if layout in ("door", "doors"):
        return [(z0, z1, door if layout == "door" else pair)]
    if layout in ("drawers", "chest"):
        return _drawer_rows(int(rng.integers(2, 5)) if layout == "drawers" else int(rng.integers(3, 6)), z0, z1, rng)
    split_z = z1 - float(rng.uniform(0.13, 0.18))  # a top drawer over doors
    return [(split_z, z1, [("drawer", "drawer", 0, place)]),
            (z0, split_z, door if layout == "drawer-over-door" else pair)]


def _drawer_rows(n: int, z0: float, z1: float, rng: np.random.Generator) -> list[Row]:
    profile = np.array(_DRAWER_PROFILES[n]) * rng.uniform(0.92, 1.08, n)
    edges = z1 - np.concatenate([[0.0], np.cumsum(profile / profile.sum())]) * (z1 - z0)
    names = [f"{_ORDINALS[i]} drawer" for i in range(n - 1)] + ["bottom drawer"]
    if n == 3:
        names[1] = "middle drawer"
    return [(float(edges[i + 1]), float(edges[i]), [("drawer", names[i], 0, "top")]) for i in range(n)]


def random_unit(role: Role, layout: str, width: float, carcass: Carcass, look: Look, split: Split,
                rng: np.random.Generator, source: str) -> UnitSpec:
    """A unit of `role` and `layout` (LAYOUTS), `width` wide, with the carcass sizes and look given; its fronts'
    mechanisms drawn from `rng`."""
    if layout not in LAYOUTS[role]:
        raise ValueError(f"a {role} unit has no layout {layout!r}: use one of {', '.join(LAYOUTS[role])}")
    c = carcass
    fronts = []
    rail = RAIL_M if look.handle.style == "edge-pull" and role != "wall" else 0.0
    for z0, z1, columns in _rows(role, layout, c.plinth_m, c.height_m - rail, rng):
        edges = np.linspace(-width / 2, width / 2, len(columns) + 1)
        for (kind, name, hinge, place), y0, y1 in zip(columns, edges[:-1], edges[1:], strict=True):
            tile = FrontSpec(kind, name, (float(y0), float(y1)), (z0, z1), hinge, look.handle_for(kind), (0.0, 0.0),
                             0.0, 0.0, Mechanism())
            handle, at = handle_position(kind, tile.size, hinge, tile.handle, place)
            lever = abs(at[0] - hinge * tile.size[0] / 2)
            tray = c.depth_m - c.front_m - c.wall_m - TRAY_CLEARANCE_M
            upper = tray - DRAWER_STOP_M if kind == "drawer" else float(np.radians(rng.uniform(95.0, 110.0)))
            mass = float(rng.uniform(1.5, 3.5) if kind == "drawer" else rng.uniform(1.5, 4.0))
            fronts.append(replace(tile, handle=handle, handle_at=at, upper=upper, mass_kg=mass,
                                  mechanism=random_mechanism(kind, lever, rng)))
    return UnitSpec(source, width, c.depth_m, c.height_m, c.plinth_m, c.wall_m, c.front_m, tuple(fronts),
                    look.body, look.front, look.handle_finish)
