"""The arm's own body in the base frame: its collision meshes posed by the measured joints and gripper opening.

Used to tell the robot's pixels from the object's (the self-filter). Meshes come from the URDF's collision
geometry (Pinocchio); each link is kept as its vertices, whose convex hull covers the link.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np
import pinocchio as pin

from drivers.errors import ArmError


class RobotBody:
    """Collision-mesh vertices of every link of `urdf`, posed by arm joints + finger joints (each finger at its
    `finger_joint_per_m` times the gripper opening; default half of it)."""

    def __init__(self, urdf: Path, arm_joints: Sequence[str], finger_joints: Sequence[str] = (),
                 finger_joint_per_m: Sequence[float] | None = None) -> None:
        urdf = Path(urdf)
        self.model = pin.buildModelFromUrdf(str(urdf))
        try:
            self.geometry = pin.buildGeomFromUrdf(self.model, str(urdf), pin.COLLISION,
                                                  package_dirs=[str(urdf.parent), str(urdf.parent.parent)])
        except (ValueError, RuntimeError) as exc:
            raise ArmError(f"robot URDF {urdf}: its collision meshes do not load ({exc}): the self-filter needs "
                           "them; check the mesh paths") from exc
        self.data, self.geometry_data = self.model.createData(), pin.GeometryData(self.geometry)
        self._arm = [self._index(name) for name in arm_joints]
        self._fingers = [self._index(name) for name in finger_joints]
        self._finger_scale = np.array(finger_joint_per_m if finger_joint_per_m is not None else
                                      [0.5] * len(finger_joints), float)
        self._vertices = [np.asarray(g.geometry.vertices(), float) * np.asarray(g.meshScale, float)
                          if hasattr(g.geometry, "vertices") else np.zeros((0, 3))
                          for g in self.geometry.geometryObjects]

    @classmethod
    def from_robot(cls, robot) -> RobotBody:
        """The body of a RobotSpec (drivers.arm.robots) or RobotConfig (built once per process and model)."""
        spec = robot.robot_spec() if hasattr(robot, "robot_spec") else robot
        return _cached(Path(spec.urdf), tuple(spec.arm_joints), tuple(spec.finger_joints),
                       tuple(spec.finger_joint_per_m))

    def _index(self, joint: str) -> int:
        if not self.model.existJointName(joint):
            raise ArmError(f"joint {joint!r} is not in the robot model: check the robot config's joint names")
        return self.model.joints[self.model.getJointId(joint)].idx_q

    def links(self, q: np.ndarray, gripper_width_m: float = 0.0) -> list[np.ndarray]:
        """Each link's mesh vertices (N, 3) in the base frame at arm joints `q`."""
        q_full = pin.neutral(self.model)
        q_full[self._arm] = q
        q_full[self._fingers] = gripper_width_m * self._finger_scale
        pin.forwardKinematics(self.model, self.data, q_full)
        pin.updateGeometryPlacements(self.model, self.data, self.geometry, self.geometry_data)
        out = []
        for placement, points in zip(self.geometry_data.oMg, self._vertices, strict=True):
            if len(points):
                out.append(points @ placement.rotation.T + placement.translation)
        return out


@lru_cache(maxsize=4)
def _cached(urdf: Path, arm_joints: tuple[str, ...], finger_joints: tuple[str, ...],
            finger_joint_per_m: tuple[float, ...]) -> RobotBody:
    return RobotBody(urdf, arm_joints, finger_joints, finger_joint_per_m)
