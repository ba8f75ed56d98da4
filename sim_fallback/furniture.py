"""What the simulated world loads as one piece of furniture, whatever made it (a procedural unit of a kitchen or a
PartNet-Mobility model): an articulated URDF, its openable parts, how each part's joint feels, and how its surfaces
look. Pure values; `SimWorld` loads them.

Furniture frame: origin at the centre of the body's footprint on the floor, x out of the front, y to the left of the
furniture (the right of someone facing it), z up; metres. A part's joint value is 0 closed and positive opening
(m for a drawer, rad for a door).

A part's `handle` is ground truth: the scripted data generator grasps it and evaluation scores against it; the
controller never sees it. Lengths are metres as loaded, after `Furniture.scale`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

PartKind = Literal["drawer", "door"]
HandleStyle = Literal["bar", "long-bar", "knob", "edge-pull", "recessed", "cup", "none"]
FinishKind = Literal["wood", "laminate", "painted", "metal"]


@dataclass(frozen=True)
class Finish:
    """How a surface looks: its material `kind`, base colour (linear RGB in 0-1), gloss (0 matte .. 1 mirror-like,
    also what makes a D415 lose depth on it) and a seed for its texture's grain."""

    kind: FinishKind = "painted"
    rgb: tuple[float, float, float] = (0.8, 0.8, 0.78)
    gloss: float = 0.1
    seed: int = 0


@dataclass(frozen=True)
class Mechanism:
    """How a part's joint resists (SI: N or N m, per m or per rad). `friction`: Coulomb friction while it moves;
    `stiction`: the extra force to start it from rest; `damping`; `spring_*`: a self-closing spring (force toward
    closed = preload + stiffness x value); `soft_close_*`: over the last `soft_close_range` before closed the part
    is pulled shut with `soft_close_force`; `catch_*`: a magnetic catch holding the closed part with
    `catch_force` (its break-away force) within `catch_range` of closed. Drawers stop at their end (the URDF
    limit)."""

    friction: float = 8.0
    damping: float = 5.0
    stiction: float = 0.0
    spring_stiffness: float = 0.0
    spring_preload: float = 0.0
    soft_close_range: float = 0.0
    soft_close_force: float = 0.0
    catch_range: float = 0.0
    catch_force: float = 0.0


@dataclass(frozen=True)
class Handle:
    """A part's handle (ground truth). In the part's link frame at joint value 0: `centre` the grip centre,
    `axis` the direction a parallel gripper's fingers close across (a bar's length direction: unit), `normal`
    out of the front (unit). Knobs, cups and pulls have an `axis` too: the way a gripper would best hold them.
    `style` "none" is a push-to-open front. `length_m` is the handle's extent along `axis`, `thickness_m` across
    it (what the fingers close on); `clear_behind_m` how far behind the grip centre (along -normal) the part's
    surface lies, its front or a recess's back: fingertips reaching further hit it (None: not known)."""

    style: HandleStyle
    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    normal: tuple[float, float, float]
    length_m: float = 0.0
    thickness_m: float = 0.0
    clear_behind_m: float | None = None


@dataclass(frozen=True)
class Part:
    """One openable part: `name` as a user says it ("top drawer", "left door", "drawer 2"), its URDF `link` and
    `joint`, `kind`, opening range `upper` (m or rad, after scaling), its handle (None when the model does not say
    where it is) and its `mechanism`."""

    name: str
    kind: PartKind
    link: str
    joint: str
    upper: float
    handle: Handle | None
    mechanism: Mechanism = Mechanism()


@dataclass(frozen=True)
class Furniture:
    """One piece of furniture ready to load: `urdf` (the file PyBullet loads), `T_urdf` (4x4: the URDF root's pose
    in the furniture frame, after `scale`, PyBullet's globalScaling), `size_m` (width, depth, height in the
    furniture frame: the room it takes, what its parts sweep past its sides and top included), its openable
    `parts`, the `finishes` of its links by link name (links not named look like their URDF colour, painted) and
    `source` (what made it, for reports: "procedural test 12", "partnet 45213").
    Equal when every field is (`T_urdf` compared element by element)."""

    urdf: Path
    T_urdf: np.ndarray
    scale: float
    size_m: tuple[float, float, float]
    parts: tuple[Part, ...]
    source: str
    finishes: dict[str, Finish] = field(default_factory=dict)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Furniture):
            return NotImplemented
        mine, theirs = vars(self).copy(), vars(other).copy()
        return np.array_equal(mine.pop("T_urdf"), theirs.pop("T_urdf")) and mine == theirs

    def part(self, name: str) -> Part:
        """The part called `name` (its name or URDF link name); KeyError listing the parts it has."""
        for p in self.parts:
            if name in (p.name, p.link):
                return p
        raise KeyError(f"{self.source} has no part {name!r}: it has {', '.join(p.name for p in self.parts) or 'none'}")
