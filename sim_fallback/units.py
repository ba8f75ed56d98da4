"""Procedural kitchen units: a carcass with fronts (drawers and doors), each front with its handle, as `Furniture`.

Unit frame = furniture frame (sim_fallback/furniture.py): origin at the footprint's centre on its bottom (a wall unit
hangs with that point at its mounting height), x out of the front, y to the unit's left (the right of someone facing
it), z up; metres. Fronts overlay the carcass: closed, their outer faces lie at x = depth / 2, GAP_M apart.

Links: `body` (carcass and plinth); per part `<kind>_<i>` and its handle `<kind>_<i>_handle` (fixed to it, its frame
at the grip centre). A drawer's link frame is its front's outer face centre; a door's is on its hinge line at the
outer face, at the door's mid-height: hinged at its outer front edge, an opening door swings clear of its neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from sim_fallback.furniture import Finish, Furniture, Mechanism, Part, PartKind
from sim_fallback.handles import HandleSpec
from sim_fallback.urdf_text import Shape, box, cached_urdf, joint_xml, link_xml, material_xml, robot_xml

GAP_M = 0.003  # between neighbouring fronts
EDGE_M = 0.045  # a door's grip centre from its free edge; a bar's end from the front's edge
TRAY_CLEARANCE_M = 0.02  # a drawer's tray stops this short of the carcass back at its end
HandlePlace = Literal["top", "bottom"]


@dataclass(frozen=True)
class FrontSpec:
    """One front: a drawer or a door (`hinge` the y side, +1 or -1, of its hinge line; 0 for a drawer) covering the
    tile `y` x `z` (lo, hi) of the unit's front, less the gaps. `handle_at`: the grip centre on the front, (y, z)
    from its centre. `upper`: opening range (m or rad)."""

    kind: PartKind
    name: str
    y: tuple[float, float]
    z: tuple[float, float]
    hinge: int
    handle: HandleSpec
    handle_at: tuple[float, float]
    upper: float
    mass_kg: float
    mechanism: Mechanism

    @property
    def size(self) -> tuple[float, float]:
        """(width, height) of the front panel."""
        return self.y[1] - self.y[0] - GAP_M, self.z[1] - self.z[0] - GAP_M

    @property
    def centre(self) -> tuple[float, float]:
        return (self.y[0] + self.y[1]) / 2, (self.z[0] + self.z[1]) / 2


@dataclass(frozen=True)
class UnitSpec:
    """One unit: outer `width_m` x `depth_m` (fronts included) x `height_m`, on a `plinth_m` (0 for a wall unit),
    carcass panels `wall_m` thick, fronts `front_thickness_m`; its `fronts`; the finishes of its carcass, fronts and
    handles. `source` names it in reports."""

    source: str
    width_m: float
    depth_m: float
    height_m: float
    plinth_m: float
    wall_m: float
    front_thickness_m: float
    fronts: tuple[FrontSpec, ...]
    body_finish: Finish
    front_finish: Finish
    handle_finish: Finish

    def links(self) -> list[str]:
        return [f"{f.kind}_{i}" for i, f in enumerate(self.fronts)]

    def furniture(self) -> Furniture:
        """The unit as loadable furniture (its URDF written once to the cache)."""
        parts = tuple(Part(f.name, f.kind, link, f"{link}_joint", f.upper, f.handle.truth(self.grip_in_link(f)),
                           f.mechanism) for f, link in zip(self.fronts, self.links(), strict=True))
        finishes = {"body": self.body_finish}
        for link in self.links():
            finishes[link], finishes[f"{link}_handle"] = self.front_finish, self.handle_finish
        stem = "".join(c if c.isalnum() else "_" for c in self.source)
        return Furniture(cached_urdf(self.urdf(), stem), np.eye(4), 1.0, (self.width_m, self.depth_m, self.height_m),
                         parts, self.source, finishes)

    def link_origin(self, front: FrontSpec) -> np.ndarray:
        """The part's link frame origin in the unit frame, closed."""
        yc, zc = front.centre
        if front.kind == "drawer":
            return np.array([self.depth_m / 2, yc, zc])
        return np.array([self.depth_m / 2, yc + front.hinge * front.size[0] / 2, zc])

    def grip_in_link(self, front: FrontSpec) -> np.ndarray:
        """The grip centre in the part's link frame."""
        dy, dz = front.handle_at
        if front.kind == "door":
            dy -= front.hinge * front.size[0] / 2
        return np.array([front.handle.standoff_m, dy, dz])

    def urdf(self) -> str:
        colours = {"body": self.body_finish, "front": self.front_finish, "handle": self.handle_finish}
        materials = [material_xml(name, (*finish.rgb, 1.0)) for name, finish in colours.items()]
        links, joints = [link_xml("body", "body", self._carcass(), 40.0)], []
        for front, link in zip(self.fronts, self.links(), strict=True):
            shapes = self._drawer(front) if front.kind == "drawer" else self._door(front)
            links += [link_xml(link, "front", shapes, front.mass_kg),
                      link_xml(f"{link}_handle", "handle", front.handle.shapes(), 0.1, friction=0.3)]
            axis = (1, 0, 0) if front.kind == "drawer" else (0, 0, front.hinge)
            joints += [joint_xml(f"{link}_joint", "prismatic" if front.kind == "drawer" else "revolute", "body",
                                 link, self.link_origin(front), axis, front.upper),
                       joint_xml(f"{link}_handle_joint", "fixed", link, f"{link}_handle", self.grip_in_link(front))]
        return robot_xml(self.source.replace(" ", "_"), materials, links, joints)

    def _carcass(self) -> list[Shape]:
        w, d, h, p, t, ft = (self.width_m, self.depth_m, self.height_m, self.plinth_m, self.wall_m,
                             self.front_thickness_m)
        dc, xc, hc = d - ft, -ft / 2, h - p  # carcass depth, its centre, its height
        shapes = [box((dc, w, t), (xc, 0, p + t / 2)), box((dc, w, t), (xc, 0, h - t / 2)),
                  box((dc, t, hc), (xc, w / 2 - t / 2, p + hc / 2)), box((dc, t, hc), (xc, -w / 2 + t / 2, p + hc / 2)),
                  box((t, w - 2 * t, hc - 2 * t), (-d / 2 + t / 2, 0, p + hc / 2))]
        if p > 0:
            shapes.append(box((dc - 0.08, w - 0.01, p), (xc - 0.03, 0, p / 2)))
        return shapes

    def tray_length(self) -> float:
        return self.depth_m - self.front_thickness_m - self.wall_m - TRAY_CLEARANCE_M

    def _drawer(self, front: FrontSpec) -> list[Shape]:
        """Front panel (frame at its outer face centre) and the tray behind it."""
        t, ft = self.wall_m, self.front_thickness_m
        fw, fh = front.size
        length, width = self.tray_length(), self.width_m - 4 * t
        height = min(fh - 0.03, 0.22)
        x, z = -ft - length / 2, -fh / 2 + 0.015 + height / 2
        return [*_panel(fw, fh, ft, (0.0, 0.0), front),
                box((length, width, t), (x, 0, -fh / 2 + 0.015 + t / 2)),
                *(box((length, t, height), (x, s * (width / 2 - t / 2), z)) for s in (-1, 1)),
                box((t, width - 2 * t, height), (-ft - length + t / 2, 0, z))]

    def _door(self, front: FrontSpec) -> list[Shape]:
        """Door panel, its frame on the hinge line."""
        return _panel(*front.size, self.front_thickness_m, (-front.hinge * front.size[0] / 2, 0.0), front)


def _panel(fw: float, fh: float, ft: float, centre: tuple[float, float], front: FrontSpec) -> list[Shape]:
    """A front panel whose outer face centre is at (0, *centre) in its link frame, with the pocket of a recessed
    pull cut out of it: the panel around the hole, the pocket's back and, deeper than the panel, its sides."""
    cy, cz = centre
    pocket = front.handle.pocket
    if pocket is None:
        return [box((ft, fw, fh), (-ft / 2, cy, cz))]
    along, across, depth = pocket
    pw, ph = (across, along) if front.handle.vertical else (along, across)
    hy, hz = cy + front.handle_at[0], cz + front.handle_at[1]
    y0, y1, z0, z1 = cy - fw / 2, cy + fw / 2, cz - fh / 2, cz + fh / 2
    py0, py1, pz0, pz1 = hy - pw / 2, hy + pw / 2, hz - ph / 2, hz + ph / 2
    x = -ft / 2
    shapes = [box((ft, py0 - y0, fh), (x, (y0 + py0) / 2, cz)), box((ft, y1 - py1, fh), (x, (py1 + y1) / 2, cz)),
              box((ft, pw, pz0 - z0), (x, hy, (z0 + pz0) / 2)), box((ft, pw, z1 - pz1), (x, hy, (pz1 + z1) / 2)),
              box((0.003, pw, ph), (-depth - 0.0015, hy, hz))]
    if depth > ft:
        extra, x = depth - ft, -ft - (depth - ft) / 2
        shapes += [box((extra, 0.002, ph), (x, y, hz)) for y in (py0, py1)]
        shapes += [box((extra, pw, 0.002), (x, hy, z)) for z in (pz0, pz1)]
    return shapes


def handle_position(kind: PartKind, size: tuple[float, float], hinge: int, handle: HandleSpec,
                    place: HandlePlace) -> tuple[HandleSpec, tuple[float, float]]:
    """Where a handle goes on a front of `size` (width, height): centred on a drawer (in its upper part when the
    drawer is deep), near a door's free edge and its `place` ("top" or "bottom"); an edge pull on the top
    edge (the bottom edge for `place` "bottom"). The handle is shortened when the front is too small for it.
    Returns it and the grip centre (y, z) from the front's centre."""
    fw, fh = size
    room = (fh if handle.vertical else fw) - 2 * EDGE_M
    if handle.length_m > room:
        handle = replace(handle, length_m=room)
    along, across = handle.footprint()
    extent_y, extent_z = (across, along) if handle.vertical else (along, across)
    if handle.style == "edge-pull":
        z = fh / 2 - handle.thickness_m / 2
        z = -z if place == "bottom" else z
    elif kind == "drawer":
        z = fh / 2 - 0.05 - extent_z / 2 if fh > 0.24 else 0.0
    else:
        z = (1.0 if place == "top" else -1.0) * max(fh / 2 - 0.06 - extent_z / 2, 0.0)
    y = 0.0 if kind == "drawer" else -hinge * (fw / 2 - max(EDGE_M, extent_y / 2 + 0.025))
    return handle, (y, z)
