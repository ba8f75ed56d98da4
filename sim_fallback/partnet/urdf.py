"""A mobility.urdf read into links, their geometries and joints, and the copy of it PyBullet loads.

Joints are read in one convention: unit axis, closed at joint value 0 and opening positive up to `upper`. A joint
whose range starts elsewhere is re-based (its frame moved to the range's start); a continuous joint gets the range
[0, CONTINUOUS_UPPER_RAD].
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sim_fallback.partnet.errors import PartNetError

CONTINUOUS_UPPER_RAD = np.radians(110.0)  # a common cabinet hinge's opening, for joints modelled without limits
MOVING_TYPES = ("prismatic", "revolute")


@dataclass(frozen=True)
class Geometry:
    """One visual or collision element of a link: an OBJ `mesh` (absolute path) or a `box` (size), its pose
    `T_link` in the link frame and its `scale`; `name` is the visual's name ("handle-6": sub-part 6)."""

    name: str
    mesh: Path | None
    box: tuple[float, float, float] | None
    T_link: np.ndarray
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Joint:
    """A joint as read: `T_parent` the joint (child link) frame in the parent link frame at value 0 (closed),
    `axis` unit in that frame, range [0, `upper`] (model units or rad; 0 for fixed joints)."""

    name: str
    type: str
    parent: str
    child: str
    T_parent: np.ndarray
    axis: np.ndarray
    upper: float


@dataclass
class MobilityUrdf:
    """The kinematic tree of a mobility.urdf: `visuals` and `collisions` by link, `joints` by child link,
    `root` the link no joint moves; `tree` is the XML, re-written by `write_copy`."""

    name: str
    folder: Path
    tree: ET.ElementTree
    visuals: dict[str, tuple[Geometry, ...]]
    collisions: dict[str, tuple[Geometry, ...]]
    joints: dict[str, Joint]
    root: str

    def link_poses(self) -> dict[str, np.ndarray]:
        """Every link's frame in the root link's frame with all joints at 0 (closed)."""
        poses = {self.root: np.eye(4)}
        pending = list(self.joints.values())
        while pending:
            ready = [j for j in pending if j.parent in poses]
            for joint in ready:
                poses[joint.child] = poses[joint.parent] @ joint.T_parent
            pending = [j for j in pending if j.child not in poses]
        return poses

    def rigid_group(self, link: str) -> list[str]:
        """`link` and the links fixed to it (through fixed joints, at any depth)."""
        group = [link]
        for name in group:
            group += [j.child for j in self.joints.values() if j.parent == name and j.type == "fixed"]
        return group

    def pybullet_text(self, inertials: dict[str, tuple[float, np.ndarray, np.ndarray]]) -> str:
        """The URDF PyBullet loads: absolute mesh paths, joints as read (unit axes, closed at 0), and each link's
        `inertials` (mass kg, centre of mass and principal moments kg m^2 in the link frame)."""
        tree = copy.deepcopy(self.tree)
        for element in tree.iter("mesh"):
            element.set("filename", str((self.folder / element.get("filename", "")).resolve()))
        for element in tree.getroot().iter("joint"):
            joint = self.joints.get(_child(element))
            if joint is not None and joint.type != "fixed":
                _write_joint(element, joint)
        for element in tree.getroot().iter("link"):
            if element.get("name") in inertials:
                _write_inertial(element, *inertials[element.get("name")])
        return '<?xml version="1.0"?>\n' + ET.tostring(tree.getroot(), encoding="unicode")


def read_mobility_urdf(path: Path, name: str) -> MobilityUrdf:
    """Parse `path` (an object's mobility.urdf, `name` for messages); one-line errors when it does not parse,
    does not form one tree, or names meshes that are missing."""
    try:
        tree = ET.parse(path)
    except (ET.ParseError, OSError) as exc:
        raise PartNetError(f"{name}: {path.name} does not parse ({exc}); fix: restore the file from the "
                           f"dataset") from exc
    root_element = tree.getroot()
    if root_element.tag != "robot":
        raise PartNetError(f"{name}: {path.name} is not a URDF (its root element is <{root_element.tag}>, not "
                           f"<robot>); fix: restore the file from the dataset")
    folder = path.parent
    try:
        links = [link.get("name") for link in root_element.iter("link")]
        visuals = {link.get("name"): tuple(_geometry(e, folder) for e in link.iter("visual"))
                   for link in root_element.iter("link")}
        collisions = {link.get("name"): tuple(_geometry(e, folder) for e in link.iter("collision"))
                      for link in root_element.iter("link")}
        joints = {joint.child: joint for joint in (_joint(e) for e in root_element.iter("joint"))}
    except (ValueError, TypeError, AttributeError) as exc:
        raise PartNetError(f"{name}: {path.name} has an invalid element ({exc}); fix: restore the file from the "
                           f"dataset") from exc
    roots = [link for link in links if link not in joints]
    unknown = sorted({n for j in joints.values() for n in (j.parent, j.child)} - set(links))
    if len(roots) != 1 or unknown:
        cause = f"joints name unknown links {unknown}" if unknown else f"{len(roots)} root links {roots[:5]}"
        raise PartNetError(f"{name}: {path.name} is not one kinematic tree ({cause}); fix: restore the file from "
                           f"the dataset")
    model = MobilityUrdf(root_element.get("name", name), folder, tree, visuals, collisions, joints, roots[0])
    _check_meshes(model, path, name)
    return model


def _check_meshes(model: MobilityUrdf, path: Path, name: str) -> None:
    meshes = {g.mesh for group in (model.visuals, model.collisions) for gs in group.values() for g in gs if g.mesh}
    missing = sorted(str(m.relative_to(path.parent)) if m.is_relative_to(path.parent) else str(m)
                     for m in meshes if not m.is_file())
    if missing:
        shown = ", ".join(missing[:3]) + (" ..." if len(missing) > 3 else "")
        raise PartNetError(f"{name}: {len(missing)} of its {len(meshes)} meshes are missing ({shown}); fix: "
                           f"download or unpack the object again (its textured_objs/ folder is incomplete)")


def _geometry(element: ET.Element, folder: Path) -> Geometry:
    shape = element.find("geometry")
    if shape is None:
        shape = ET.Element("geometry")
    mesh, box = shape.find("mesh"), shape.find("box")
    return Geometry(element.get("name", ""),
                    (folder / mesh.get("filename", "")).resolve() if mesh is not None else None,
                    tuple(_floats(box.get("size"), 3)) if box is not None else None,
                    _origin(element.find("origin")),
                    tuple(_floats(mesh.get("scale", "1 1 1"), 3)) if mesh is not None else (1.0, 1.0, 1.0))


def _joint(element: ET.Element) -> Joint:
    kind = element.get("type", "")
    parent, child = element.find("parent").get("link"), _child(element)
    T = _origin(element.find("origin"))
    if kind not in ("fixed", "prismatic", "revolute", "continuous"):
        raise ValueError(f"joint {element.get('name')} of type {kind!r} (fixed, prismatic, revolute or continuous)")
    if kind == "fixed":
        return Joint(element.get("name"), kind, parent, child, T, np.zeros(3), 0.0)
    axis_element = element.find("axis")
    axis = np.array(_floats(axis_element.get("xyz", "1 0 0") if axis_element is not None else "1 0 0", 3))
    if np.linalg.norm(axis) < 1e-9:
        raise ValueError(f"joint {element.get('name')} has a zero axis")
    axis = axis / np.linalg.norm(axis)
    limit = element.find("limit")
    if kind == "continuous" or limit is None:
        lower, upper = 0.0, (0.0 if kind == "prismatic" else CONTINUOUS_UPPER_RAD)
    else:
        lower, upper = float(limit.get("lower", 0.0)), float(limit.get("upper", 0.0))
    if upper < lower:
        raise ValueError(f"joint {element.get('name')} has lower limit {lower} above its upper {upper}")
    T_start = np.eye(4)
    if kind == "prismatic":
        T_start[:3, 3] = axis * lower
    else:
        T_start[:3, :3] = Rotation.from_rotvec(axis * lower).as_matrix()
    joint_type = "prismatic" if kind == "prismatic" else "revolute"
    return Joint(element.get("name"), joint_type, parent, child, T @ T_start, axis, upper - lower)


def _write_joint(element: ET.Element, joint: Joint) -> None:
    element.set("type", joint.type)
    origin = element.find("origin")
    if origin is None:
        origin = ET.SubElement(element, "origin")
    xyz, rpy = joint.T_parent[:3, 3], Rotation.from_matrix(joint.T_parent[:3, :3]).as_euler("xyz")
    origin.set("xyz", _text(xyz))
    origin.set("rpy", _text(rpy))
    axis = element.find("axis")
    if axis is None:
        axis = ET.SubElement(element, "axis")
    axis.set("xyz", _text(joint.axis))
    limit = element.find("limit")
    if limit is None:
        limit = ET.SubElement(element, "limit")
    limit.attrib.update({"lower": "0", "upper": f"{joint.upper:.9g}", "effort": "1000", "velocity": "10"})


def _write_inertial(link: ET.Element, mass: float, com: np.ndarray, moments: np.ndarray) -> None:
    for old in link.findall("inertial"):
        link.remove(old)
    inertial = ET.Element("inertial")
    ET.SubElement(inertial, "origin", xyz=_text(com), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=f"{mass:.6g}")
    ixx, iyy, izz = (f"{m:.6g}" for m in moments)
    ET.SubElement(inertial, "inertia", ixx=ixx, iyy=iyy, izz=izz, ixy="0", ixz="0", iyz="0")
    link.insert(0, inertial)


def _origin(element: ET.Element | None) -> np.ndarray:
    T = np.eye(4)
    if element is not None:
        T[:3, 3] = _floats(element.get("xyz", "0 0 0"), 3)
        T[:3, :3] = Rotation.from_euler("xyz", _floats(element.get("rpy", "0 0 0"), 3)).as_matrix()
    return T


def _child(element: ET.Element) -> str:
    return element.find("child").get("link")


def _floats(text: str, n: int) -> list[float]:
    values = [float(v) for v in text.split()]
    if len(values) == 1 and n == 3:
        values *= 3
    if len(values) != n:
        raise ValueError(f"{text!r} is not {n} numbers")
    return values


def _text(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in values)
