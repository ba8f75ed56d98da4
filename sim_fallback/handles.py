"""Handles of procedural fronts: their shapes, the pocket a recessed pull needs, and their ground truth.

Handle frame: origin at the grip centre, x out of the front, the bar (or a knob's, cup's or pull's holding
direction) along y when horizontal and along z when vertical; metres. A parallel gripper's fingers close across
the bar: a bar or a recessed pull's bar across its diameter, a knob across its diameter, an edge pull across its
tab (a thin plate standing out of the front's edge), a cup across its shell's height.

Families: the train and test size intervals are disjoint, and the test family has styles train lacks (knobs, cups).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim_fallback.furniture import Handle, HandleStyle
from sim_fallback.urdf_text import Shape, box, cylinder

STYLES = {"train": ("bar", "long-bar", "edge-pull", "recessed"),
          "test": ("bar", "long-bar", "edge-pull", "recessed", "knob", "cup")}
# (low, high) per split and style: length along the bar, thickness across it, standoff of the grip centre
_SIZES: dict[tuple[str, str], dict[str, tuple[float, float]]] = {
    ("train", "bar"): {"length": (0.10, 0.18), "thickness": (0.012, 0.016), "standoff": (0.035, 0.045)},
    ("test", "bar"): {"length": (0.19, 0.25), "thickness": (0.017, 0.020), "standoff": (0.046, 0.055)},
    ("train", "long-bar"): {"length": (0.26, 0.36), "thickness": (0.012, 0.016), "standoff": (0.035, 0.045)},
    ("test", "long-bar"): {"length": (0.37, 0.48), "thickness": (0.017, 0.020), "standoff": (0.046, 0.055)},
    ("train", "edge-pull"): {"length": (0.10, 0.16), "thickness": (0.004, 0.005), "standoff": (0.013, 0.016)},
    ("test", "edge-pull"): {"length": (0.17, 0.25), "thickness": (0.0055, 0.007), "standoff": (0.017, 0.020)},
    ("train", "recessed"): {"length": (0.10, 0.16), "thickness": (0.008, 0.009), "standoff": (-0.010, -0.007)},
    ("test", "recessed"): {"length": (0.17, 0.24), "thickness": (0.0095, 0.011), "standoff": (-0.014, -0.011)},
    ("test", "knob"): {"length": (0.025, 0.035), "thickness": (0.025, 0.035), "standoff": (0.028, 0.036)},
    ("test", "cup"): {"length": (0.080, 0.095), "thickness": (0.028, 0.035), "standoff": (0.020, 0.025)},
}
POCKET_CLEARANCE_M = 0.035  # a recessed pull's pocket leaves this much room above and below its bar for a finger
POCKET_BEHIND_BAR_M = 0.015  # ... and this much behind it
PLATE_M = 0.003  # a cup's shell
POST_M = 0.01  # a bar's posts, a knob's stem


@dataclass(frozen=True)
class HandleSpec:
    """One handle: `style`, `vertical` (its bar along z, else along y), `length_m` along the bar (a knob's or a
    cup's width), `thickness_m` across it, `standoff_m` from the front's surface out to the grip centre (negative:
    behind it, in a recess)."""

    style: HandleStyle
    vertical: bool
    length_m: float
    thickness_m: float
    standoff_m: float

    @property
    def bar(self) -> np.ndarray:
        return np.array([0.0, 0.0, 1.0]) if self.vertical else np.array([0.0, 1.0, 0.0])

    @property
    def pocket(self) -> tuple[float, float, float] | None:
        """A recessed pull's pocket in the front: (along the bar, across it, depth behind the surface); else None."""
        if self.style != "recessed":
            return None
        return (self.length_m, self.thickness_m + 2 * POCKET_CLEARANCE_M,
                -self.standoff_m + self.thickness_m / 2 + POCKET_BEHIND_BAR_M)

    def footprint(self) -> tuple[float, float]:
        """Its extent on the front: (along the bar, across it), pocket included."""
        if self.pocket is not None:
            return self.pocket[0], self.pocket[1]
        return self.length_m, self.thickness_m

    def shapes(self) -> list[Shape]:
        """Its shapes in the handle frame (the front's surface at x = -standoff_m)."""
        s, b, length = self.standoff_m, self.thickness_m, self.length_m
        along = "z" if self.vertical else "y"

        def at(u: float, v: float = 0.0, x: float = 0.0) -> tuple[float, float, float]:
            """(x, along the bar u, across it v) in handle coordinates."""
            return (x, v, u) if self.vertical else (x, u, v)

        def sized(sx: float, su: float, sv: float) -> tuple[float, float, float]:
            return (sx, sv, su) if self.vertical else (sx, su, sv)

        if self.style in ("bar", "long-bar"):
            post_len = s - b / 2
            ends = length / 2 - 0.015
            return [cylinder(b / 2, length, (0, 0, 0), along),
                    *(box(sized(post_len, POST_M, POST_M), at(e, 0, -s + post_len / 2)) for e in (-ends, ends))]
        if self.style == "recessed":
            return [cylinder(b / 2, length, (0, 0, 0), along)]
        if self.style == "knob":
            head = 0.018
            stem = s - head / 2
            return [cylinder(b / 2, head, (0, 0, 0), "x"), cylinder(POST_M / 2, stem, (-s + stem / 2, 0, 0), "x")]
        if self.style == "edge-pull":  # a tab out of the front's edge, the grip centre mid-way along it
            return [box(sized(2 * s, length, b), at(0.0))]
        if self.style == "cup":  # a shell open below: outer plate, top plate, two sides
            return [box(sized(PLATE_M, length, b), at(0.0)),
                    box(sized(s, length, PLATE_M), at(0.0, b / 2 - PLATE_M / 2, -s / 2)),
                    *(box(sized(s, PLATE_M, b), at(e, 0.0, -s / 2)) for e in (-length / 2, length / 2))]
        raise ValueError(f"handle style {self.style!r} has no shapes: use one of {', '.join(STYLES['test'])}")

    def truth(self, centre_in_link: np.ndarray) -> Handle:
        """The ground truth of this handle with its grip centre at `centre_in_link` (the part's link frame, whose x
        is out of the front)."""
        behind = self.thickness_m / 2 + POCKET_BEHIND_BAR_M if self.pocket is not None else self.standoff_m
        return Handle(self.style, tuple(float(v) for v in centre_in_link), tuple(float(v) for v in self.bar),
                      (1.0, 0.0, 0.0), self.length_m, self.thickness_m, behind)


def random_handle(style: str, split: str, vertical: bool, rng: np.random.Generator) -> HandleSpec:
    """A handle of `style` from the `split` family, its bar vertical or not."""
    if style not in STYLES[split]:
        raise ValueError(f"handle style {style!r} is not in the {split} family: use one of {', '.join(STYLES[split])}")
    r = _SIZES[(split, style)]
    length, thickness, standoff = (float(rng.uniform(*r[k])) for k in ("length", "thickness", "standoff"))
    if style == "knob":
        length = thickness
    return HandleSpec(style, vertical, length, thickness, standoff)  # type: ignore[arg-type]
