"""The part a user means: a furniture's parts of a kind in the order a user counts them, and `--part` text resolved.

Order: top to bottom, then left to right as someone facing the furniture (and a camera in front of it) sees them;
fronts whose centres lie within ROW_M of each other in height form one row. A user names a part by its name ("top
drawer", "left door"), an index N (0 = the first of the task's kind in that order), the model's link name, or
"top|bottom|left|right <kind>" (the first or last in that order, the leftmost or rightmost).
"""

from __future__ import annotations

from sim_fallback.errors import PartError
from sim_fallback.furniture import Furniture, PartKind
from sim_fallback.furniture_body import PartGeometry

ROW_M = 0.05


def ordered(geometry: list[PartGeometry], kind: PartKind) -> list[PartGeometry]:
    """The parts of `kind`, top to bottom then left to right (furniture y grows to the right of someone facing it)."""
    parts = sorted((g for g in geometry if g.kind == kind), key=lambda g: -g.front_centre[2])
    rows: list[list[PartGeometry]] = []
    for g in parts:
        if rows and abs(rows[-1][0].front_centre[2] - g.front_centre[2]) < ROW_M:
            rows[-1].append(g)
        else:
            rows.append([g])
    return [g for row in rows for g in sorted(row, key=lambda g: g.front_centre[1])]


def describe(furniture: Furniture, geometry: list[PartGeometry], kind: PartKind) -> str:
    """"0 top drawer (link drawer_0), 1 bottom drawer (link drawer_1)": the parts of `kind` as a user can name them."""
    links = {p.name: p.link for p in furniture.parts}
    return ", ".join(f"{i} {g.name} (link {links[g.name]})" for i, g in enumerate(ordered(geometry, kind))) or "none"


def resolve(furniture: Furniture, geometry: list[PartGeometry], kind: PartKind, text: str) -> PartGeometry:
    """The part of `kind` that `text` names; PartError listing the parts of that kind otherwise."""
    parts = ordered(geometry, kind)
    wanted = " ".join(text.lower().split())
    by_link = {p.link.lower(): p.name for p in furniture.parts}
    name = by_link.get(wanted, wanted)
    for g in parts:
        if g.name.lower() == name:
            return g
    if wanted.isdigit() and int(wanted) < len(parts):
        return parts[int(wanted)]
    words = wanted.split()
    if parts and len(words) == 2 and words[1] == kind and words[0] in ("top", "bottom", "left", "right"):
        lowest = min(g.front_centre[2] for g in parts)
        pick = {"top": lambda: parts[0], "bottom": lambda: next(g for g in parts if g.front_centre[2] - lowest < ROW_M),
                "left": lambda: min(parts, key=lambda g: g.front_centre[1]),
                "right": lambda: max(parts, key=lambda g: g.front_centre[1])}[words[0]]
        return pick()
    other = [g for g in geometry if g.name.lower() == name and g.kind != kind]
    cause = f"is a {other[0].kind}, not a {kind}" if other else "is not one of its parts"
    raise PartError(f"--part {text!r} {cause} in {furniture.source}: its {kind}s are "
                     f"{describe(furniture, geometry, kind)}; give one of those names, an index, or a link name")
