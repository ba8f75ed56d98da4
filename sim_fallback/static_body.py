"""Static shapes merged into one PyBullet body: the first shape is its base, every other a link fixed to it (one
body keeps the world's body count low; a link per shape keeps a finish per shape)."""

from __future__ import annotations

import numpy as np
import pybullet as pb

from sim_fallback.layout import StaticShape, pose_matrix


def static_body(client: int, shapes: tuple[StaticShape, ...]) -> int:
    """One fixed body made of `shapes` (at least one); link k + 1 is shape k + 1 (the base, -1, is shape 0)."""
    collisions, visuals = zip(*(_shape(client, s) for s in shapes), strict=True)
    base = shapes[0]
    position, quat = _placement(base.pose)
    if len(shapes) == 1:
        return pb.createMultiBody(0.0, collisions[0], visuals[0], position, quat, physicsClientId=client)
    from_base = np.linalg.inv(pose_matrix(base.pose))
    relative = [from_base @ pose_matrix(s.pose) for s in shapes[1:]]
    n = len(relative)
    return pb.createMultiBody(
        0.0, collisions[0], visuals[0], position, quat,
        linkMasses=[0.0] * n, linkCollisionShapeIndices=list(collisions[1:]),
        linkVisualShapeIndices=list(visuals[1:]), linkPositions=[T[:3, 3].tolist() for T in relative],
        linkOrientations=[pb.getQuaternionFromEuler([0.0, 0.0, float(np.arctan2(T[1, 0], T[0, 0]))]) for T in relative],
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n, linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n,
        linkParentIndices=[0] * n, linkJointTypes=[pb.JOINT_FIXED] * n, linkJointAxis=[[0.0, 0.0, 1.0]] * n,
        physicsClientId=client)


def _placement(pose) -> tuple[list[float], list[float]]:
    x, y, z, yaw = pose
    return [x, y, z], list(pb.getQuaternionFromEuler([0.0, 0.0, yaw]))


def _shape(client: int, shape: StaticShape) -> tuple[int, int]:
    if shape.kind == "box":
        half = [v / 2 for v in shape.size]
        return (pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=client),
                pb.createVisualShape(pb.GEOM_BOX, halfExtents=half, rgbaColor=shape.rgba, physicsClientId=client))
    radius, height = shape.size[0] / 2, shape.size[2]
    return (pb.createCollisionShape(pb.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=client),
            pb.createVisualShape(pb.GEOM_CYLINDER, radius=radius, length=height, rgbaColor=shape.rgba,
                                 physicsClientId=client))
