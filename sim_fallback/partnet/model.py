"""A PartNet-Mobility object read: its URDF, which links are drawers and doors, which meshes are their handles,
and its shapes in the URDF root's frame (model units, every joint closed).

Parts: a `slider` link labelled a drawer is a drawer, a `hinge` link labelled a door (door, rotation_door ...) is
a door (semantics.txt); other moving links (buttons, lids, sliding doors) are not parts. A part's handle is the
meshes of its "handle" sub-parts (mobility_v2.json) and of any link fixed to it named as a handle.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim_fallback.furniture import PartKind
from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.frame import opening_direction
from sim_fallback.partnet.layout import ObjectFiles, read_object_files
from sim_fallback.partnet.meshes import geometry_mesh, missing_textures, transformed
from sim_fallback.partnet.urdf import MobilityUrdf, read_mobility_urdf

PART_JOINTS: dict[PartKind, tuple[str, str]] = {"drawer": ("slider", "prismatic"),  # semantics kind, URDF joint
                                                "door": ("hinge", "revolute")}
_SUB_PART_ID = re.compile(r"-(\d+)$")  # a visual's name ends with its sub-part id: "handle-6"
VisualKey = tuple[str, int]  # (link, index of the visual in the link)


@dataclass(frozen=True)
class Openable:
    """A drawer or door link."""

    link: str
    kind: PartKind


class PartNetModel:
    """One object folder read (one-line errors when it cannot be used). Points are in the URDF root's frame, in
    model units, with every joint at 0 (closed); `points[link]` leaves the handles out."""

    def __init__(self, folder: Path) -> None:
        self.files: ObjectFiles = read_object_files(folder)
        self.urdf: MobilityUrdf = read_mobility_urdf(self.files.urdf, self.files.source)
        self._check_textures()
        self.openable = [Openable(link, kind) for link, kind in self._openable()]
        self.poses = self.urdf.link_poses()
        self.handles = {p.link: self._handle_visuals(p.link) for p in self.openable}
        skip = {key for keys in self.handles.values() for key in keys}
        self.points = {link: self._points([(link, i) for i in range(len(gs)) if (link, i) not in skip])
                       for link, gs in self.urdf.visuals.items()}

    @property
    def source(self) -> str:
        return self.files.source

    def model_axes(self) -> np.ndarray:
        """The model's axes (columns x, y = up, z) in the root frame: the orientation of the meshes of the link
        with the most of them."""
        link = max(self.urdf.visuals, key=lambda k: len(self.urdf.visuals[k]))
        if not self.urdf.visuals[link]:
            raise PartNetError(f"{self.source}: its links have no meshes; fix: restore mobility.urdf from the dataset")
        return (self.poses[link] @ self.urdf.visuals[link][0].T_link)[:3, :3]

    def body_points(self) -> np.ndarray:
        """Every link's points but the handles'."""
        return np.concatenate([p for p in self.points.values() if len(p)])

    def part_points(self, link: str) -> np.ndarray:
        """The points of a part: its link and the links fixed to it, handles left out."""
        return np.concatenate([self.points[member] for member in self.urdf.rigid_group(link)])

    def handle_points(self, link: str) -> np.ndarray | None:
        """The points of a part's handle (None when the model has none)."""
        return self._points(self.handles[link]) if self.handles[link] else None

    def opening_direction(self, link: str) -> np.ndarray:
        """Which way a part starts to move as it opens (unit, root frame)."""
        joint, T = self.urdf.joints[link], self.poses[link]
        part = self.part_points(link)
        centre = (part.min(axis=0) + part.max(axis=0)) / 2
        return opening_direction(joint.type, T[:3, :3] @ joint.axis, T[:3, 3], centre)

    def ignored_links(self) -> list[str]:
        """One line for each moving link that is not a part, saying why."""
        parts = {p.link for p in self.openable}
        lines = []
        for link, semantic in self.files.semantics.items():
            joint = self.urdf.joints.get(link)
            if link in parts or joint is None or joint.type == "fixed":
                continue
            described = f"{link} ({semantic.joint_kind} {semantic.label}, {joint.type} joint)"
            if not any(kind in semantic.label for kind in PART_JOINTS):
                lines.append(f"{described}: not a drawer or door")
            elif joint.upper <= 0:
                lines.append(f"{described}: its joint has no range")
            elif not self._has_meshes(link):
                lines.append(f"{described}: it has no meshes")
            else:
                lines.append(f"{described}: only slider drawers and hinged doors are parts")
        return lines

    def semantics_text(self) -> str:
        """semantics.txt in one line (its first six links)."""
        lines = [f"{s.link} {s.joint_kind} {s.label}" for s in self.files.semantics.values()]
        return "semantics.txt: " + ("; ".join(lines[:6]) + (" ..." if len(lines) > 6 else "") if lines else "empty")

    def _openable(self) -> list[tuple[str, PartKind]]:
        found = []
        for link, semantic in self.files.semantics.items():
            joint = self.urdf.joints.get(link)
            for kind, (semantic_kind, joint_type) in PART_JOINTS.items():
                if (semantic.joint_kind == semantic_kind and kind in semantic.label and joint is not None
                        and joint.type == joint_type and joint.upper > 0 and self._has_meshes(link)):
                    found.append((link, kind))
        return found

    def _has_meshes(self, link: str) -> bool:
        return any(self.urdf.visuals[member] for member in self.urdf.rigid_group(link))

    def _handle_visuals(self, link: str) -> list[VisualKey]:
        ids = self.files.handle_ids.get(link, frozenset())
        keys = []
        for member in self.urdf.rigid_group(link):
            for index, visual in enumerate(self.urdf.visuals[member]):
                match = _SUB_PART_ID.search(visual.name)
                if (match and int(match.group(1)) in ids) or (member != link and "handle" in member.lower()):
                    keys.append((member, index))
        return keys

    def _points(self, keys: list[VisualKey]) -> np.ndarray:
        found = [transformed(self.poses[link], geometry_mesh(self.urdf.visuals[link][i])[0]) for link, i in keys]
        return np.concatenate(found) if found else np.zeros((0, 3))

    def _check_textures(self) -> None:
        """A one-line error when textures the meshes' materials name are missing (PyBullet would warn at length
        and draw those meshes untextured)."""
        folder = self.files.folder
        missing = missing_textures(sorted({g.mesh for gs in self.urdf.visuals.values() for g in gs if g.mesh}))
        if missing:
            shown = ", ".join(str(m.relative_to(folder)) if m.is_relative_to(folder) else str(m) for m in missing[:3])
            raise PartNetError(f"{self.source}: {len(missing)} texture(s) its meshes name are missing ({shown}"
                               f"{' ...' if len(missing) > 3 else ''}); fix: download or unpack the object again "
                               f"(its images/ folder is incomplete)")
