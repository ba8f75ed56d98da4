"""URDF text of furniture built from boxes and cylinders (no mesh files), and a cache that writes it once.

Lengths in metres; every shape is centred at `xyz` in its link's frame.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

Rgba = tuple[float, float, float, float]
_RPY = {"x": "0 1.570796 0", "y": "1.570796 0 0", "z": "0 0 0"}  # turns a URDF cylinder's z axis onto this axis


@dataclass(frozen=True)
class Shape:
    """A box (`size`: x, y, z extents) or a cylinder (`size`: radius, length, with its axis along `axis`)."""

    kind: Literal["box", "cylinder"]
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    axis: Literal["x", "y", "z"] = "z"

    @property
    def extent(self) -> np.ndarray:
        """Its axis-aligned extent (x, y, z) in the link frame."""
        if self.kind == "box":
            return np.array(self.size, float)
        radius, length = self.size
        return np.array([length if a == self.axis else 2 * radius for a in "xyz"])


def box(size: tuple[float, float, float] | np.ndarray, xyz: tuple[float, float, float] | np.ndarray) -> Shape:
    return Shape("box", tuple(float(v) for v in size), tuple(float(v) for v in xyz))  # type: ignore[arg-type]


def cylinder(radius: float, length: float, xyz, axis: Literal["x", "y", "z"]) -> Shape:
    return Shape("cylinder", (float(radius), float(length)), tuple(float(v) for v in xyz), axis)  # type: ignore


def shape_xml(shape: Shape) -> str:
    x, y, z = shape.xyz
    if shape.kind == "box":
        geometry = '<box size="{:.5f} {:.5f} {:.5f}"/>'.format(*shape.size)
        rpy = "0 0 0"
    else:
        geometry = '<cylinder radius="{:.5f}" length="{:.5f}"/>'.format(*shape.size)
        rpy = _RPY[shape.axis]
    return f'<origin xyz="{x:.5f} {y:.5f} {z:.5f}" rpy="{rpy}"/><geometry>{geometry}</geometry>'


def link_xml(name: str, material: str, shapes: list[Shape], mass: float, friction: float | None = None) -> str:
    """A link drawn and colliding as `shapes`; inertia of their bounding box, centred on it."""
    lo = np.min([np.subtract(s.xyz, s.extent / 2) for s in shapes], axis=0)
    hi = np.max([np.add(s.xyz, s.extent / 2) for s in shapes], axis=0)
    (cx, cy, cz), (sx, sy, sz) = (lo + hi) / 2, hi - lo
    ixx, iyy, izz = (mass / 12 * (a * a + b * b) for a, b in ((sy, sz), (sx, sz), (sx, sy)))
    visuals = "".join(f'<visual>{shape_xml(s)}<material name="{material}"/></visual>' for s in shapes)
    collisions = "".join(f"<collision>{shape_xml(s)}</collision>" for s in shapes)
    contact = "" if friction is None else f'<contact><lateral_friction value="{friction}"/></contact>'
    return (f'<link name="{name}"><inertial><origin xyz="{cx:.5f} {cy:.5f} {cz:.5f}"/><mass value="{mass:.4f}"/>'
            f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/></inertial>'
            f"{visuals}{collisions}{contact}</link>")


def joint_xml(name: str, kind: Literal["prismatic", "revolute", "fixed"], parent: str, child: str,
              xyz: np.ndarray | tuple, axis: np.ndarray | tuple | None = None, upper: float = 0.0) -> str:
    x, y, z = (float(v) for v in xyz)
    text = (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{x:.5f} {y:.5f} {z:.5f}" rpy="0 0 0"/>')
    if kind != "fixed":
        ax = " ".join(f"{float(v):g}" for v in axis)  # type: ignore[union-attr]
        text += f'<axis xyz="{ax}"/><limit lower="0" upper="{upper:.5f}" effort="1000" velocity="10"/>'
    return text + "</joint>"


def material_xml(name: str, rgba: Rgba) -> str:
    return f'<material name="{name}"><color rgba="{" ".join(f"{c:.3f}" for c in rgba)}"/></material>'


def robot_xml(name: str, materials: list[str], links: list[str], joints: list[str]) -> str:
    body = "\n  ".join([*materials, *links, *joints])
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n  {body}\n</robot>\n'


def cached_urdf(text: str, stem: str) -> Path:
    """`text` written once per machine under the user's cache directory, named by `stem` and its content (the same
    text is the same file); written whole or not at all, so parallel workers never read half a file."""
    directory = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "axisloop" / "furniture"
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{stem}_{hashlib.sha1(text.encode()).hexdigest()[:16]}.urdf"
    if not path.exists():
        partial = path.with_name(f"{path.stem}.{os.getpid()}.tmp")
        partial.write_text(text)
        os.replace(partial, path)
    return path
