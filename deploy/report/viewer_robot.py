"""The robot in the rerun viewer: its URDF through rerun's URDF support, posed by joint values.

The model is logged once (static) from a light copy of the URDF: each link drawn with its collision meshes where it
has any (a few hundred kB for the Panda, where its visual meshes weigh about 5 MB in a recording) and every mesh
path made absolute (`package://NAME/...` resolved against the folders around the URDF, as pybullet_data's robots
lay them out). Each pose logs the movable joints' transforms (`UrdfJoint.compute_transform`) on the `time`
timeline; the root link hangs in the `world` entity's frame (the robot's base frame).
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np

ROOT_ENTITY = "world"  # the URDF's entities go under world/ROBOT_NAME
JOINTS_ENTITY = "world/robot_joints"  # where the joints' transforms are logged (one entity per joint below it)


class RobotModel:
    """A robot's URDF in a rerun recording. `arm_joints` are the joints that joint vectors list, in order;
    `finger_joints` each take half the gripper's opening (a parallel gripper's two fingers)."""

    def __init__(self, rr, urdf: Path, arm_joints: Sequence[str], finger_joints: Sequence[str] = ()) -> None:
        self.rr = rr
        with tempfile.TemporaryDirectory() as folder:
            light = Path(folder) / Path(urdf).name
            light.write_bytes(light_urdf(Path(urdf)))
            self.tree = rr.urdf.UrdfTree.from_file_path(light, entity_path_prefix=ROOT_ENTITY)
        self.arm_joints = [self._joint(name) for name in arm_joints]
        self.finger_joints = [self._joint(name) for name in finger_joints]

    def _joint(self, name: str):
        joint = self.tree.get_joint_by_name(name)
        if joint is None:
            raise ValueError(f"joint {name!r} is not in the URDF of {self.tree.name!r}")
        return joint

    @property
    def name(self) -> str:
        return self.tree.name

    def log(self, rec) -> None:
        """The model (static): its geometry and fixed joints, the root link in the world's frame."""
        rec.send_chunks(self.tree.stream(include_joint_transforms=False))
        moving = {j.name for j in [*self.arm_joints, *self.finger_joints]}
        for joint in self.tree.joints():
            if joint.name not in moving:  # fixed (or not driven): its transform at zero, for good
                rec.log(f"{JOINTS_ENTITY}/{joint.name}", joint.compute_transform(0.0, clamp=False), static=True)
        root = self.tree.root_link().name
        rec.log(f"{JOINTS_ENTITY}/{root}", self.rr.Transform3D(parent_frame=f"tf#/{ROOT_ENTITY}", child_frame=root),
                static=True)

    def pose(self, rec, q: np.ndarray, gripper_width_m: float | None = None) -> None:
        """The joints at `q` (rad or m, `arm_joints`' order) and the fingers at half of `gripper_width_m` each (their
        upper limit, open, when not known), at the recording's current time."""
        for joint, value in zip(self.arm_joints, np.ravel(q), strict=False):
            rec.log(f"{JOINTS_ENTITY}/{joint.name}", joint.compute_transform(float(value), clamp=False))
        for joint in self.finger_joints:
            value = joint.limit_upper if gripper_width_m is None else gripper_width_m / 2
            value = float(np.clip(value, joint.limit_lower, joint.limit_upper))
            rec.log(f"{JOINTS_ENTITY}/{joint.name}", joint.compute_transform(value, clamp=False))


def light_urdf(urdf: Path) -> bytes:
    """The URDF with each link drawn by its collision geometry where it has any (its visuals dropped) and every mesh
    file an absolute path."""
    tree = ET.parse(urdf)
    for link in tree.getroot().iter("link"):
        collisions = link.findall("collision")
        if collisions:
            for visual in link.findall("visual"):
                link.remove(visual)
            for collision in collisions:
                collision.tag = "visual"
    for mesh in tree.getroot().iter("mesh"):
        mesh.set("filename", str(resolve_mesh(mesh.get("filename", ""), urdf.parent)))
    return ET.tostring(tree.getroot(), encoding="utf-8", xml_declaration=True)


def resolve_mesh(filename: str, folder: Path) -> str:
    """A mesh reference as an absolute path: `package://NAME/REST` found as NAME/REST in the URDF's folder or one
    above it, `file://PATH` and relative paths from the URDF's folder; unchanged when nothing is there."""
    if filename.startswith("package://"):
        rest = filename.removeprefix("package://")
        for base in (folder, *folder.parents):
            if (base / rest).is_file():
                return str((base / rest).resolve())
        return filename
    path = Path(filename.removeprefix("file://"))
    path = path if path.is_absolute() else folder / path
    return str(path.resolve()) if path.is_file() else filename
