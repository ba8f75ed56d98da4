"""A PartNet-Mobility object as a `Furniture`: its drawers and doors, its pose and size as real furniture, and the
URDF copy PyBullet loads.

Parts: a `slider` link labelled a drawer is a drawer, a `hinge` link labelled a door (door, rotation_door ...) is
a door (semantics.txt); other links (buttons, lids, sliding doors) are not parts. A part's handle is the meshes of
its "handle" sub-parts (mobility_v2.json) and any link fixed to it named as a handle.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from sim_fallback.furniture import Furniture, Mechanism, Part, PartKind
from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.frame import (
    footprint_pose,
    front_direction,
    furniture_rotation,
    nearest_horizontal_axis,
    opening_direction,
)
from sim_fallback.partnet.handles import handle_in_link, handle_truth
from sim_fallback.partnet.layout import ObjectFiles, read_object_files
from sim_fallback.partnet.meshes import geometry_mesh, transformed
from sim_fallback.partnet.naming import grid_positions, part_names
from sim_fallback.partnet.sizes import real_scale
from sim_fallback.partnet.urdf import MobilityUrdf, read_mobility_urdf

ScaleRule = Literal["real", "native"]
SCALE_RULES: tuple[ScaleRule, ...] = ("real", "native")
PART_JOINTS = {"drawer": ("slider", "prismatic"), "door": ("hinge", "revolute")}  # semantics kind, URDF joint
MECHANISMS: dict[PartKind, Mechanism] = {  # the middle of the procedural cabinets' ranges (cabinet_urdf.py)
    "drawer": Mechanism(friction=8.0, damping=5.0),
    "door": Mechanism(friction=1.0, damping=1.0),
}
BOARD_KG_PER_M2 = 10.0  # a link's mass per m^2 of its bounding box's three faces (15 mm board, ~680 kg/m^3)
_SUB_PART_ID = re.compile(r"-(\d+)$")  # a visual's name ends with its sub-part id: "handle-6"


@dataclass(frozen=True)
class _Openable:
    link: str
    kind: PartKind


def load_partnet(folder: Path, part: str | None = None, scale: ScaleRule = "real") -> Furniture:
    """The object in `folder` (one PartNet-Mobility object: mobility.urdf, semantics.txt ...) as furniture.

    scale: "real" sizes it as a real piece of its category (sizes.py); "native" keeps the model's own units as
    metres (what the paper and RGBManip load). part: when given, a part name or link name the object must have.
    """
    if scale not in SCALE_RULES:
        raise PartNetError(f"scale {scale!r}: unknown; fix: use one of {', '.join(SCALE_RULES)}")
    files = read_object_files(folder)
    urdf = read_mobility_urdf(files.urdf, files.source)
    openable = openable_links(files, urdf)
    if not openable:
        raise PartNetError(f"{files.source}: no drawer or door part ({_semantics_text(files)}); fix: choose an "
                           f"object with a slider drawer or a hinged door")
    poses = urdf.link_poses()
    handles = {p.link: _handle_visuals(files, urdf, p.link) for p in openable}
    handle_names = {key for keys in handles.values() for key in keys}
    points = {link: _link_points(urdf, poses, link, handle_names) for link in urdf.visuals}
    model_axes = _model_axes(urdf, poses)
    up = model_axes[:, 1]
    directions = {p.link: _opening_direction(urdf, poses, points, p.link) for p in openable}
    R = furniture_rotation(front_direction(list(directions.values()), model_axes, up), up)
    body = np.concatenate([p for p in points.values() if len(p)])
    _, native_size = footprint_pose(R, body, 1.0)
    s = real_scale(native_size, files.category) if scale == "real" else 1.0
    T_urdf, size = footprint_pose(R, body, s)
    parts = _parts(urdf, poses, points, handles, openable, directions, model_axes, R, s)
    furniture = Furniture(urdf=_write_copy(files, urdf, s), T_urdf=T_urdf, scale=s, size_m=tuple(map(float, size)),
                          parts=parts, source=files.source)
    if part is not None:
        try:
            furniture.part(part)
        except KeyError:
            raise PartNetError(f"{files.source} has no part {part!r}: it has {_part_list(parts)}; fix: name one "
                               f"of these (or its link)") from None
    return furniture


def openable_links(files: ObjectFiles, urdf: MobilityUrdf) -> list[_Openable]:
    """The drawer and door links of an object (see the module's rule), in semantics.txt's order."""
    found = []
    for link, semantic in files.semantics.items():
        joint = urdf.joints.get(link)
        for kind, (semantic_kind, joint_type) in PART_JOINTS.items():
            if (semantic.joint_kind == semantic_kind and kind in semantic.label and joint is not None
                    and joint.type == joint_type and joint.upper > 0):
                found.append(_Openable(link, kind))
    return found


def ignored_links(files: ObjectFiles, urdf: MobilityUrdf) -> list[str]:
    """One line for each moving link that is not a part, saying why."""
    parts = {p.link for p in openable_links(files, urdf)}
    lines = []
    for link, semantic in files.semantics.items():
        joint = urdf.joints.get(link)
        if link in parts or joint is None or joint.type == "fixed":
            continue
        described = f"{link} ({semantic.joint_kind} {semantic.label}, {joint.type} joint)"
        if not any(kind in semantic.label for kind in PART_JOINTS):
            lines.append(f"{described}: not a drawer or door")
        elif joint.upper <= 0:
            lines.append(f"{described}: its joint has no range")
        else:
            lines.append(f"{described}: only slider drawers and hinged doors are parts")
    return lines


def _parts(urdf, poses, points, handles, openable, directions, model_axes, R, s) -> tuple[Part, ...]:
    """The parts with names, ranges, handles (in their link frames, scaled) and mechanisms, ordered drawers
    then doors, each top to bottom then left to right as someone facing the front sees them."""
    up_f = np.array([0.0, 0.0, 1.0])
    parts = []
    for kind in ("drawer", "door"):
        links = [p.link for p in openable if p.kind == kind]
        if not links:
            continue
        spans = [_front_span(R @ np.concatenate([points[k] for k in urdf.rigid_group(link)]).T * s)
                 for link in links]
        positions = grid_positions(np.array(spans))
        order = sorted(range(len(links)), key=lambda i: positions[i])
        names = part_names(kind, [positions[i] for i in order])
        for name, i in zip(names, order, strict=True):
            link = links[i]
            joint = urdf.joints[link]
            normal = R @ nearest_horizontal_axis(directions[link], model_axes, model_axes[:, 1])
            handle = None
            if handles[link]:
                handle_points = np.concatenate([_visual_points(urdf, poses, key) for key in handles[link]])
                front = np.concatenate([points[k] for k in urdf.rigid_group(link)])
                in_front = handle_truth(handle_points @ R.T * s, front @ R.T * s, normal, up_f)
                handle = handle_in_link(in_front, R @ poses[link][:3, :3], s * R @ poses[link][:3, 3])
            upper = joint.upper * s if joint.type == "prismatic" else joint.upper
            parts.append(Part(name=name, kind=kind, link=link, joint=joint.name, upper=float(upper), handle=handle,
                              mechanism=MECHANISMS[kind]))
    return tuple(parts)


def _front_span(points_f: np.ndarray) -> tuple[float, float, float, float]:
    """Lateral (furniture y: toward the right of someone facing the front) and vertical spans of points (3, n)
    in the furniture frame."""
    y, z = points_f[1], points_f[2]
    return float(y.min()), float(y.max()), float(z.min()), float(z.max())


VisualKey = tuple[str, int]  # (link, index of the visual in the link)


def _handle_visuals(files: ObjectFiles, urdf: MobilityUrdf, link: str) -> list[VisualKey]:
    """The visuals that make the part `link`'s handle: its handle sub-parts', and those of links fixed to it
    that are named as handles."""
    ids = files.handle_ids.get(link, frozenset())
    keys = []
    for member in urdf.rigid_group(link):
        for index, visual in enumerate(urdf.visuals[member]):
            match = _SUB_PART_ID.search(visual.name)
            if (match and int(match.group(1)) in ids) or (member != link and "handle" in member.lower()):
                keys.append((member, index))
    return keys


def _visual_points(urdf: MobilityUrdf, poses: dict, key: VisualKey) -> np.ndarray:
    link, index = key
    return transformed(poses[link], geometry_mesh(urdf.visuals[link][index])[0])


def _link_points(urdf: MobilityUrdf, poses: dict, link: str, skip: set[VisualKey]) -> np.ndarray:
    """Vertices of a link's visuals but those in `skip`, in the root frame (model units), closed."""
    found = [_visual_points(urdf, poses, (link, i)) for i in range(len(urdf.visuals[link])) if (link, i) not in skip]
    return np.concatenate(found) if found else np.zeros((0, 3))


def _model_axes(urdf: MobilityUrdf, poses: dict) -> np.ndarray:
    """The model's axes (columns x, y = up, z) in the root frame: the orientation of the meshes of the link
    with the most visuals."""
    link = max(urdf.visuals, key=lambda k: len(urdf.visuals[k]))
    if not urdf.visuals[link]:
        raise PartNetError(f"{urdf.name}: its links have no meshes; fix: restore mobility.urdf from the dataset")
    return (poses[link] @ urdf.visuals[link][0].T_link)[:3, :3]


def _opening_direction(urdf: MobilityUrdf, poses: dict, points: dict, link: str) -> np.ndarray:
    joint, T = urdf.joints[link], poses[link]
    part = np.concatenate([points[k] for k in urdf.rigid_group(link)])
    centre = (part.min(axis=0) + part.max(axis=0)) / 2 if len(part) else T[:3, 3]
    return opening_direction(joint.type, T[:3, :3] @ joint.axis, T[:3, 3], centre)


def _inertials(urdf: MobilityUrdf, s: float) -> dict[str, tuple[float, np.ndarray, np.ndarray]]:
    """Each link's mass (BOARD_KG_PER_M2), centre and box moments from its meshes' bounds at scale `s`."""
    inertials = {}
    for link, visuals in urdf.visuals.items():
        found = [geometry_mesh(v)[0] for v in visuals]
        pts = np.concatenate(found) * s if found else np.zeros((1, 3))
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        a, b, c = np.maximum(hi - lo, 1e-3)
        mass = max(BOARD_KG_PER_M2 * (a * b + b * c + a * c), 0.01)
        moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        inertials[link] = (mass, (lo + hi) / 2 / s, moments)
    return inertials


def _write_copy(files: ObjectFiles, urdf: MobilityUrdf, s: float) -> Path:
    """The URDF copy PyBullet loads, in the user's cache ($XDG_CACHE_HOME/axisloop/partnet), named by its
    content (written once, renamed into place so parallel workers never read half a file)."""
    text = urdf.pybullet_text(_inertials(urdf, s))
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "axisloop" / "partnet"
    path = cache / f"{files.object_id}_{digest}.urdf"
    if not path.exists():
        cache.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f"{path.stem}.{os.getpid()}.urdf")
        partial.write_text(text)
        os.replace(partial, path)
    return path


def _semantics_text(files: ObjectFiles) -> str:
    lines = [f"{s.link} {s.joint_kind} {s.label}" for s in files.semantics.values()]
    return "semantics.txt: " + ("; ".join(lines[:6]) + (" ..." if len(lines) > 6 else "") if lines else "empty")


def _part_list(parts: tuple[Part, ...]) -> str:
    return ", ".join(f"{p.name} ({p.link})" for p in parts)
