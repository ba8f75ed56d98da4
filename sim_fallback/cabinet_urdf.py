"""Procedural articulated cabinets: a body with one drawer (prismatic) or one door (revolute) and a handle.

Cabinet frame: origin at the centre of the body's bottom, x out of the front face, y to the left of the
cabinet (the right of someone facing it), z up; metres. Links: `body` (root), `drawer` or `door`, `handle`
(fixed to the moving part, its frame at the grip centre). The joint is 0 when closed, positive opening.

Two disjoint families like the paper's train/test objects: separate seed streams and non-overlapping size
ranges; the test family also has knob handles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim_fallback.furniture import Furniture, Handle, Mechanism, Part
from sim_fallback.urdf_text import cached_urdf

Kind = Literal["drawer", "door"]
Split = Literal["train", "test"]
Rgba = tuple[float, float, float, float]

KINDS = ("drawer", "door")
SPLITS = ("train", "test")

# (low, high) per split; the train and test intervals of every body size are disjoint.
_RANGES: dict[tuple[str, str], dict[str, tuple[float, float]]] = {
    ("drawer", "train"): {"width": (0.40, 0.55), "depth": (0.35, 0.45), "height": (0.30, 0.48),
                          "front": (0.12, 0.19), "bar_length": (0.10, 0.18), "bar_thickness": (0.012, 0.016),
                          "standoff": (0.035, 0.045)},
    ("drawer", "test"): {"width": (0.56, 0.68), "depth": (0.46, 0.54), "height": (0.50, 0.62),
                         "front": (0.20, 0.26), "bar_length": (0.19, 0.25), "bar_thickness": (0.017, 0.020),
                         "standoff": (0.046, 0.055)},
    ("door", "train"): {"width": (0.30, 0.42), "depth": (0.30, 0.40), "height": (0.40, 0.58),
                        "bar_length": (0.10, 0.16), "bar_thickness": (0.012, 0.016),
                        "standoff": (0.035, 0.045)},
    ("door", "test"): {"width": (0.43, 0.52), "depth": (0.41, 0.50), "height": (0.60, 0.72),
                       "bar_length": (0.17, 0.24), "bar_thickness": (0.017, 0.020),
                       "standoff": (0.046, 0.055)},
}
_HANDLE_STYLES = {"train": ("bar",), "test": ("bar", "knob")}


@dataclass(frozen=True)
class CabinetSpec:
    """One cabinet. Sizes in metres; joint limit in m (drawer) or rad (door); friction in N or N m,
    damping in N s/m or N m s/rad (applied by the world after loading: PyBullet ignores URDF friction).

    front_height_m: height of the drawer front (a door covers the whole front); handle_offset_m: the grip
    centre on the moving front, (lateral, vertical) from the front's centre; hinge: side of the door's
    hinge seen by someone facing the cabinet.
    """

    kind: Kind
    split: Split
    seed: int
    width_m: float
    depth_m: float
    height_m: float
    wall_m: float
    front_thickness_m: float
    front_height_m: float
    hinge: Literal["left", "right"] | None
    handle_style: Literal["bar", "knob"]
    handle_length_m: float
    handle_thickness_m: float
    handle_standoff_m: float
    handle_offset_m: tuple[float, float]
    joint_upper: float
    moving_mass_kg: float
    friction: float
    damping: float
    body_rgba: Rgba
    front_rgba: Rgba
    handle_rgba: Rgba

    @property
    def joint_origin_cabinet(self) -> np.ndarray:
        """Joint frame origin in the cabinet frame: the drawer front's centre, or the door's hinge line."""
        top = self.height_m - self.wall_m
        if self.kind == "drawer":
            return np.array([self.depth_m / 2, 0.0, top - self.front_height_m / 2])
        side = -1.0 if self.hinge == "left" else 1.0
        return np.array([self.depth_m / 2, side * self.width_m / 2, self.height_m / 2])

    @property
    def joint_axis_cabinet(self) -> np.ndarray:
        """Unit joint axis in the cabinet frame; a positive joint value opens."""
        if self.kind == "drawer":
            return np.array([1.0, 0.0, 0.0])
        return np.array([0.0, 0.0, -1.0 if self.hinge == "left" else 1.0])

    @property
    def handle_in_joint(self) -> np.ndarray:
        """Grip centre in the joint frame at joint value 0."""
        lateral, vertical = self.handle_offset_m
        if self.kind == "drawer":
            return np.array([self.handle_standoff_m, lateral, vertical])
        toward_free_edge = 1.0 if self.hinge == "left" else -1.0
        return np.array([self.front_thickness_m + self.handle_standoff_m,
                         toward_free_edge * (self.width_m + lateral), vertical])

    @property
    def handle_cabinet(self) -> np.ndarray:
        """Grip centre in the cabinet frame when closed."""
        return self.joint_origin_cabinet + self.handle_in_joint

    @property
    def handle_vertical(self) -> bool:
        """True when the bar runs vertically (doors), False when horizontal (drawers); knobs count as bars."""
        return self.kind == "door"


def random_cabinet(kind: Kind, seed: int, split: Split = "train") -> CabinetSpec:
    """A random cabinet of `kind` from the `split` family, deterministic from (kind, seed, split)."""
    if kind not in KINDS or split not in SPLITS:
        raise ValueError(f"cabinet kind {kind!r} / split {split!r}: kind must be one of {KINDS}, "
                         f"split one of {SPLITS}")
    if seed < 0:
        raise ValueError(f"cabinet seed {seed}: seeds must be >= 0")
    rng = np.random.default_rng([SPLITS.index(split), KINDS.index(kind), seed])
    r = _RANGES[(kind, split)]

    def u(name: str) -> float:
        return float(rng.uniform(*r[name]))

    width, depth, height = u("width"), u("depth"), u("height")
    wall = float(rng.uniform(0.012, 0.02))
    front_t = float(rng.uniform(0.015, 0.022))
    style = str(rng.choice(_HANDLE_STYLES[split]))
    bar_length, bar_t, standoff = u("bar_length"), u("bar_thickness"), u("standoff")
    if style == "knob":
        bar_length = bar_t = float(rng.uniform(0.025, 0.035))
    if kind == "drawer":
        front_h = min(u("front"), height - 2 * wall)
        hinge = None
        offset = (float(rng.uniform(-0.03, 0.03)), float(rng.uniform(-0.2, 0.2) * front_h))
        upper = float(rng.uniform(0.50, 0.56))
        mass, friction, damping = (float(rng.uniform(*b)) for b in ((1.5, 3.0), (6.0, 10.0), (3.0, 7.0)))
    else:
        front_h = height
        hinge = str(rng.choice(["left", "right"]))
        edge = float(rng.uniform(0.04, 0.07))  # grip centre to the free edge
        offset = (-edge, float(rng.uniform(-0.15, 0.15) * height))
        upper = float(np.radians(rng.uniform(80.0, 95.0)))
        mass, friction, damping = (float(rng.uniform(*b)) for b in ((2.0, 4.0), (0.6, 1.4), (0.6, 1.4)))

    def colour(lo: float, hi: float) -> Rgba:
        return (*(round(float(c), 3) for c in rng.uniform(lo, hi, 3)), 1.0)

    return CabinetSpec(
        kind=kind, split=split, seed=seed, width_m=width, depth_m=depth, height_m=height, wall_m=wall,
        front_thickness_m=front_t, front_height_m=front_h, hinge=hinge, handle_style=style,
        handle_length_m=bar_length, handle_thickness_m=bar_t, handle_standoff_m=standoff,
        handle_offset_m=offset, joint_upper=upper, moving_mass_kg=mass, friction=friction, damping=damping,
        body_rgba=colour(0.35, 0.9), front_rgba=colour(0.3, 0.85), handle_rgba=colour(0.05, 0.3),
    )


def cabinet_urdf(spec: CabinetSpec) -> str:
    """URDF text of the cabinet (boxes only, so it needs no mesh files)."""
    w, d, h, t = spec.width_m, spec.depth_m, spec.height_m, spec.wall_m
    panels = [((d, w, t), (0, 0, t / 2)), ((d, w, t), (0, 0, h - t / 2)),
              ((d, t, h), (0, w / 2 - t / 2, h / 2)), ((d, t, h), (0, -w / 2 + t / 2, h / 2)),
              ((t, w, h), (-d / 2 + t / 2, 0, h / 2))]
    visuals = None
    if spec.kind == "drawer":
        below = h - 2 * t - spec.front_height_m  # fixed front panel under the drawer opening
        if below > 0.005:
            shelf = ((d - t, w - 2 * t, t), (t / 2, 0, t + below + t / 2))
            panels += [((t, w - 2 * t, below), (d / 2 - t / 2, 0, t + below / 2)), shelf]
            visuals = _closed_bottom_visuals(spec, [shelf])
    body = _link("body", "body_colour", panels, mass=20.0, visuals=visuals)
    moving = _drawer_link(spec) if spec.kind == "drawer" else _door_link(spec)
    handle = _link("handle", "handle_colour", _handle_boxes(spec), mass=0.1, friction=0.3)
    jx, jy, jz = spec.joint_origin_cabinet
    ax = " ".join(f"{v:g}" for v in spec.joint_axis_cabinet)
    joint_type = "prismatic" if spec.kind == "drawer" else "revolute"
    hx, hy, hz = spec.handle_in_joint
    return f"""<?xml version="1.0"?>
<robot name="cabinet_{spec.kind}_{spec.split}_{spec.seed}">
  {_material("body_colour", spec.body_rgba)}
  {_material("front_colour", spec.front_rgba)}
  {_material("handle_colour", spec.handle_rgba)}
  {body}
  {moving}
  {handle}
  <joint name="{spec.kind}_joint" type="{joint_type}">
    <parent link="body"/><child link="{spec.kind}"/>
    <origin xyz="{jx:.6f} {jy:.6f} {jz:.6f}" rpy="0 0 0"/>
    <axis xyz="{ax}"/>
    <limit lower="0" upper="{spec.joint_upper:.6f}" effort="1000" velocity="10"/>
  </joint>
  <joint name="handle_joint" type="fixed">
    <parent link="{spec.kind}"/><child link="handle"/>
    <origin xyz="{hx:.6f} {hy:.6f} {hz:.6f}" rpy="0 0 0"/>
  </joint>
</robot>
"""


def cabinet_furniture(spec: CabinetSpec) -> Furniture:
    """The cabinet as loadable furniture (its URDF written once to the cache): one part, named as its kind, whose
    mechanism is its friction and damping. No finishes: it is drawn in its URDF colours."""
    bar = (0.0, 0.0, 1.0) if spec.handle_vertical else (0.0, -1.0, 0.0)
    handle = Handle(spec.handle_style, tuple(float(v) for v in spec.handle_in_joint), bar, (1.0, 0.0, 0.0),
                    spec.handle_length_m, spec.handle_thickness_m, spec.handle_standoff_m)
    part = Part(spec.kind, spec.kind, spec.kind, f"{spec.kind}_joint", spec.joint_upper, handle,
                Mechanism(friction=spec.friction, damping=spec.damping))
    return Furniture(cached_urdf(cabinet_urdf(spec), f"cabinet_{spec.kind}_{spec.split}_{spec.seed}"), np.eye(4), 1.0,
                     (spec.width_m, spec.depth_m, spec.height_m), (part,), f"box {spec.split} {spec.kind} {spec.seed}")


Boxes = list[tuple[tuple[float, float, float], tuple[float, float, float]]]  # (size, centre) pairs


def _closed_bottom_visuals(spec: CabinetSpec, shelf: Boxes) -> Boxes:
    """What a drawer body with a closed compartment under the drawer looks like from outside: that
    compartment as one solid box under the `shelf` it keeps, then top, sides and back above it. Same
    surfaces seen from outside as the panels, but TinyRenderer shades fewer hidden pixels (about 6 ms
    a 640x480 frame)."""
    w, d, h, t = spec.width_m, spec.depth_m, spec.height_m, spec.wall_m
    bottom_h = h - t - spec.front_height_m  # the bottom panel and the fixed front under the drawer
    upper, z = h - bottom_h, (h + bottom_h) / 2
    return [((d, w, bottom_h), (0, 0, bottom_h / 2)), *shelf, ((d, w, t), (0, 0, h - t / 2)),
            ((d, t, upper), (0, w / 2 - t / 2, z)), ((d, t, upper), (0, -w / 2 + t / 2, z)),
            ((t, w, upper), (-d / 2 + t / 2, 0, z))]


def _drawer_link(spec: CabinetSpec) -> str:
    """Drawer front flush with the body's front at joint 0 (frame at the front face), tray behind it."""
    t, ft, gap = spec.wall_m, spec.front_thickness_m, 0.003
    fw, fh = spec.width_m - 2 * t - 2 * gap, spec.front_height_m - 2 * gap
    length = spec.depth_m - ft - t - 0.01
    tray_h = fh - 0.02
    x_mid = -ft - length / 2
    boxes: Boxes = [((ft, fw, fh), (-ft / 2, 0, 0)),
                    ((length, fw - 0.01, t), (x_mid, 0, -fh / 2 + t / 2)),
                    ((length, t, tray_h), (x_mid, fw / 2 - 0.005 - t / 2, -fh / 2 + tray_h / 2)),
                    ((length, t, tray_h), (x_mid, -fw / 2 + 0.005 + t / 2, -fh / 2 + tray_h / 2)),
                    ((t, fw - 0.01, tray_h), (-ft - length + t / 2, 0, -fh / 2 + tray_h / 2))]
    return _link("drawer", "front_colour", boxes, mass=spec.moving_mass_kg)


def _door_link(spec: CabinetSpec) -> str:
    """Door panel over the whole front, frame on the hinge line at mid-height."""
    toward_free_edge = 1.0 if spec.hinge == "left" else -1.0
    ft = spec.front_thickness_m
    boxes: Boxes = [((ft, spec.width_m, spec.height_m), (ft / 2, toward_free_edge * spec.width_m / 2, 0))]
    return _link("door", "front_colour", boxes, mass=spec.moving_mass_kg)


def _handle_boxes(spec: CabinetSpec) -> Boxes:
    """Bar on two standoffs (or a knob on one), in the handle frame at the grip centre; the front is at
    x = -standoff."""
    s, b, length = spec.handle_standoff_m, spec.handle_thickness_m, spec.handle_length_m
    post_len, post = s - b / 2, 0.01
    post_x = -s + post_len / 2
    if spec.handle_style == "knob":
        return [((b, b, b), (0, 0, 0)), ((post_len, post, post), (post_x, 0, 0))]
    ends = length / 2 - 0.015
    post_size = (post_len, post, post)
    if spec.handle_vertical:
        return [((b, b, length), (0, 0, 0)), *((post_size, (post_x, 0, e)) for e in (-ends, ends))]
    return [((b, length, b), (0, 0, 0)), *((post_size, (post_x, e, 0)) for e in (-ends, ends))]


def _link(name: str, material: str, boxes: Boxes, mass: float, friction: float | None = None,
          visuals: Boxes | None = None) -> str:
    """A link made of boxes (drawn as `visuals` when given); inertia of the boxes' bounding box with the
    origin at the link frame."""
    lo = np.min([np.subtract(c, np.divide(s, 2)) for s, c in boxes], axis=0)
    hi = np.max([np.add(c, np.divide(s, 2)) for s, c in boxes], axis=0)
    com = (lo + hi) / 2
    sx, sy, sz = hi - lo
    ixx, iyy, izz = (mass / 12 * (a * a + b * b) for a, b in ((sy, sz), (sx, sz), (sx, sy)))
    shapes = [f'<visual>{_box(size, centre)}<material name="{material}"/></visual>'
              for size, centre in (boxes if visuals is None else visuals)]
    shapes += [f"<collision>{_box(size, centre)}</collision>" for size, centre in boxes]
    contact = "" if friction is None else f'<contact><lateral_friction value="{friction}"/></contact>'
    cx, cy, cz = com
    return f"""<link name="{name}">
    <inertial><origin xyz="{cx:.6f} {cy:.6f} {cz:.6f}" rpy="0 0 0"/><mass value="{mass:.4f}"/>
      <inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/></inertial>
    {"".join(shapes)}{contact}
  </link>"""


def _box(size: tuple[float, float, float], centre: tuple[float, float, float]) -> str:
    (bx, by, bz), (cx, cy, cz) = size, centre
    return (f'<origin xyz="{cx:.6f} {cy:.6f} {cz:.6f}" rpy="0 0 0"/>'
            f'<geometry><box size="{bx:.6f} {by:.6f} {bz:.6f}"/></geometry>')


def _material(name: str, rgba: Rgba) -> str:
    return f'<material name="{name}"><color rgba="{" ".join(f"{c:g}" for c in rgba)}"/></material>'
