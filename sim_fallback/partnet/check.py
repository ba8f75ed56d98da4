"""Checks of a loaded `Furniture` in PyBullet (evaluation side: reads the model's truth): each part opens when its
joint is driven and its link moves as the joint says, its handle's grip centre is on the part's own collision
shapes, and a gripper's fingers have room either side of the handle and in front of it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from sim_fallback.furniture import Furniture, Part, PartKind
from sim_fallback.furniture_body import link_pose
from sim_fallback.partnet.errors import PartNetError

PHYSICS_HZ = 240
DRIVE_FRACTION = 0.8  # parts are driven to this fraction of their range
DRIVE_S = 2.0  # ... for this long
POSE_TOLERANCE_M = 0.002  # the link's frame within this of where the joint value puts it ...
LEVER_M = 0.5  # ... its turn counted as the shift of a point this far from its origin
PROBE_RADIUS_M = 0.006  # a fingertip's half thickness
FINGER_GAP_M = 0.004  # between a finger's pad and the handle's side
FRONT_DEPTH_M = 0.05  # a grip centre on a part's front lies within this of the part's outermost point (x) ...
SPAN_MARGIN_M = 0.01  # ... and within its lateral and vertical span widened by this


@dataclass(frozen=True)
class PartCheck:
    """What `check_part` measured: the joint value reached (m or rad) against its target, how far the link's
    frame is from where that value puts it (m), how far the handle's grip centre is from the part's collision
    shapes (m, negative inside; None without a handle or when another link is nearer) and whether a fingertip
    fits either side of the handle and in front of it. `problems` lists what failed, one line each."""

    part: str
    target: float
    reached: float
    pose_error_m: float
    grip_distance_m: float | None
    fingers_free: bool | None
    problems: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def check_furniture(furniture: Furniture) -> list[PartCheck]:
    """Check every part of `furniture`, each in a fresh PyBullet client (see the module)."""
    return [check_part(furniture, part) for part in furniture.parts]


def check_part(furniture: Furniture, part: Part) -> PartCheck:
    """Load `furniture` at the origin of a DIRECT client, check `part`'s handle with the part closed, then drive
    its joint to DRIVE_FRACTION of its range (position control, the others held) and compare the link's pose."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        body, links = _load(furniture, client)
        index = links[part.link]
        closed = link_pose(client, body, index)
        grip, on_front, free = _handle_checks(body, index, part, closed, links, client)
        target = DRIVE_FRACTION * part.upper
        for j in range(pb.getNumJoints(body, physicsClientId=client)):
            pb.setJointMotorControl2(body, j, pb.POSITION_CONTROL, targetPosition=target if j == index else 0.0,
                                     force=500.0, physicsClientId=client)
        for _ in range(int(DRIVE_S * PHYSICS_HZ)):
            pb.stepSimulation(physicsClientId=client)
        reached = pb.getJointState(body, index, physicsClientId=client)[0]
        info = pb.getJointInfo(body, index, physicsClientId=client)
        axis = closed[:3, :3] @ np.asarray(info[13])
        expected = _moved(closed, info[2], axis / np.linalg.norm(axis), reached)  # a joint value is m or rad
        actual = link_pose(client, body, index)
    finally:
        pb.disconnect(client)
    turn = Rotation.from_matrix(actual[:3, :3] @ expected[:3, :3].T).magnitude()
    error = float(np.linalg.norm(actual[:3, 3] - expected[:3, 3]) + LEVER_M * turn)
    problems = []
    probe = np.asarray(part.handle.centre) if part.handle is not None else np.zeros(3)
    outward = (actual[:3, :3] @ probe + actual[:3, 3] - closed[:3, :3] @ probe - closed[:3, 3])[0]
    if part.kind == "drawer" or part.handle is not None:
        if outward <= 0:
            problems.append(f"{part.name}: opening moves it {outward * 1000:.0f} mm along the front's normal")
    if abs(reached - target) > 0.02 * part.upper:
        problems.append(f"{part.name}: driven to {target:.3f} it reached {reached:.3f}")
    if error > POSE_TOLERANCE_M:
        problems.append(f"{part.name}: its link is {error * 1000:.1f} mm from where its joint value puts it")
    if part.handle is not None and grip is None:
        problems.append(f"{part.name}: another link is nearer its handle's grip centre than the part")
    elif grip is not None and grip > part.handle.thickness_m / 2:
        problems.append(f"{part.name}: its handle's grip centre is {grip * 1000:.0f} mm off the part's shapes")
    if on_front is False:
        problems.append(f"{part.name}: its handle's grip centre is not on the part's front")
    if free is False:
        problems.append(f"{part.name}: no room for the fingers either side of its handle")
    return PartCheck(part.name, target, float(reached), error, grip, free, tuple(problems))


def grip_points(furniture: Furniture) -> dict[str, np.ndarray]:
    """Where each part would be held, closed, in the furniture frame (m), by part name: its handle's grip centre,
    or the middle of its front (the outer face of its collision shapes) when the model has no handle."""
    client = pb.connect(pb.DIRECT)
    try:
        body, links = _load(furniture, client)
        points = {}
        for part in furniture.parts:
            index = links[part.link]
            if part.handle is not None:
                T = link_pose(client, body, index)
                points[part.name] = T[:3, :3] @ np.asarray(part.handle.centre) + T[:3, 3]
            else:
                lo, hi = (np.asarray(c) for c in pb.getAABB(body, index, physicsClientId=client))
                points[part.name] = np.array([hi[0], (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2])
        return points
    finally:
        pb.disconnect(client)


def parts_within_reach(furniture: Furniture, T_base_furniture: np.ndarray, reach_m: float,
                       kind: PartKind | None = None) -> list[Part]:
    """The parts (of `kind`, or all) whose grip point lies within `reach_m` of the robot base's origin, the
    furniture standing at `T_base_furniture` (4x4, furniture frame in the robot base frame); a one-line error
    naming the nearest one when none does."""
    candidates = [p for p in furniture.parts if kind is None or p.kind == kind]
    if not candidates:
        raise PartNetError(f"{furniture.source}: no {kind} part (it has {', '.join(p.name for p in furniture.parts)}); "
                           f"fix: choose another task or object")
    points = grip_points(furniture)
    distance = {p.name: float(np.linalg.norm(T_base_furniture[:3, :3] @ points[p.name] + T_base_furniture[:3, 3]))
                for p in candidates}
    within = [p for p in candidates if distance[p.name] <= reach_m]
    if not within:
        nearest = min(candidates, key=lambda p: distance[p.name])
        raise PartNetError(f"{furniture.source}: no {kind or 'drawer or door'} within the arm's reach ({reach_m:.2f} "
                           f"m of its base): the nearest, {nearest.name}, is {distance[nearest.name]:.2f} m away; "
                           f"fix: place the object nearer the robot, or choose another part or object")
    return within


def _load(furniture: Furniture, client: int) -> tuple[int, dict[str, int]]:
    """`furniture` loaded fixed at the origin of `client`, and its link indices by name."""
    body = pb.loadURDF(str(furniture.urdf), furniture.T_urdf[:3, 3].tolist(),
                       Rotation.from_matrix(furniture.T_urdf[:3, :3]).as_quat().tolist(),
                       useFixedBase=True, globalScaling=furniture.scale, physicsClientId=client)
    links = {pb.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
             for j in range(pb.getNumJoints(body, physicsClientId=client))}
    return body, links


def _handle_checks(body: int, index: int, part: Part, closed: np.ndarray, links: dict[str, int],
                   client: int) -> tuple[float | None, bool | None, bool | None]:
    """How far the handle's grip centre is from the part's collision shapes (None: another link is nearer),
    whether it lies on the part's front (the furniture's x), and whether a fingertip fits at the fingers' places
    either side of the handle and just in front of it."""
    if part.handle is None:
        return None, None, None
    h = part.handle
    centre = closed[:3, :3] @ np.asarray(h.centre) + closed[:3, 3]
    normal, axis = closed[:3, :3] @ np.asarray(h.normal), closed[:3, :3] @ np.asarray(h.axis)
    own = {index} | {j for j in links.values() if _fixed_to(body, j, index, client)}
    nearest = _touching(body, centre, 0.05, client)
    grip = float(nearest[0][8]) if nearest and nearest[0][4] in own else None
    lo, hi = (np.asarray(c) for c in pb.getAABB(body, index, physicsClientId=client))
    on_front = bool(centre[0] >= hi[0] - FRONT_DEPTH_M and np.all(centre[1:] >= lo[1:] - SPAN_MARGIN_M)
                    and np.all(centre[1:] <= hi[1:] + SPAN_MARGIN_M))
    offset = h.thickness_m / 2 + FINGER_GAP_M + PROBE_RADIUS_M
    places = [centre + side * offset * np.cross(normal, axis) for side in (1.0, -1.0)] + [centre + offset * normal]
    return grip, on_front, not any(_touching(body, p, 0.0, client) for p in places)


def _touching(body: int, point: np.ndarray, distance: float, client: int) -> list:
    """Closest points (PyBullet's tuples, nearest first) between `body` and a fingertip-sized sphere at
    `point`, within `distance`."""
    shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=PROBE_RADIUS_M, physicsClientId=client)
    sphere = pb.createMultiBody(0.0, shape, -1, point.tolist(), physicsClientId=client)
    try:
        return sorted(pb.getClosestPoints(sphere, body, distance, physicsClientId=client), key=lambda c: c[8])
    finally:
        pb.removeBody(sphere, physicsClientId=client)


def _fixed_to(body: int, joint: int, index: int, client: int) -> bool:
    """Whether link `joint` hangs from link `index` through fixed joints only."""
    while True:
        info = pb.getJointInfo(body, joint, physicsClientId=client)
        if info[2] != pb.JOINT_FIXED:
            return False
        if info[16] == index:
            return True
        if info[16] < 0:
            return False
        joint = info[16]


def _moved(closed: np.ndarray, joint_type: int, axis: np.ndarray, value: float) -> np.ndarray:
    """The link frame `closed` moved by `value` along (prismatic) or about (revolute, through its origin)
    `axis`."""
    T = closed.copy()
    if joint_type == pb.JOINT_PRISMATIC:
        T[:3, 3] += value * axis
    else:
        T[:3, :3] = Rotation.from_rotvec(value * axis).as_matrix() @ closed[:3, :3]
    return T
