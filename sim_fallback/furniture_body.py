"""`Furniture` in PyBullet: loading it at a pose, finding its links, and measuring its parts closed.

A part's pixels and its grip are its link and the links fixed to it (a handle that is its own link).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from sim_fallback.furniture import Furniture, Part


def load_furniture(client: int, furniture: Furniture, T_base: np.ndarray, yaw: float) -> int:
    """Load `furniture` with its frame at `T_base` (a turn by `yaw` about z and a shift), root fixed, every joint
    closed; its body id."""
    R_urdf, p_urdf = furniture.T_urdf[:3, :3], furniture.T_urdf[:3, 3]
    identity = np.array_equal(R_urdf, np.eye(3))
    q_urdf = (0.0, 0.0, 0.0, 1.0) if identity else tuple(Rotation.from_matrix(R_urdf).as_quat())
    q_yaw = pb.getQuaternionFromEuler([0.0, 0.0, yaw])
    position = T_base[:3, 3] + T_base[:3, :3] @ p_urdf
    quat = _quat_product(q_yaw, q_urdf)
    return pb.loadURDF(str(furniture.urdf), position.tolist(), quat, useFixedBase=True,
                       globalScaling=furniture.scale, physicsClientId=client)


def _quat_product(a, b) -> list[float]:
    """a * b, quaternions as (x, y, z, w)."""
    (ax, ay, az, aw), (bx, by, bz, bw) = a, b
    return [aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz]


def link_indices(client: int, body: int) -> dict[str, int]:
    """Link name -> index (the root link: -1)."""
    names = {pb.getBodyInfo(body, physicsClientId=client)[0].decode(): -1}
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        names[pb.getJointInfo(body, j, physicsClientId=client)[12].decode()] = j
    return names


def part_links(client: int, body: int, link: int) -> tuple[int, ...]:
    """`link` and the links fixed to it, recursively (its pixels)."""
    links = [link]
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        info = pb.getJointInfo(body, j, physicsClientId=client)
        if info[2] == pb.JOINT_FIXED and info[16] in links:
            links.append(j)
    return tuple(links)


def link_pose(client: int, body: int, link: int) -> np.ndarray:
    """4x4 pose of a link's URDF frame."""
    state = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)
    T = np.eye(4)
    T[:3, :3] = np.reshape(pb.getMatrixFromQuaternion(state[5]), (3, 3))
    T[:3, 3] = state[4]
    return T


def grip_frame(client: int, body: int, link: int, part: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(grip centre, bar axis, front normal) of `part` now, in the frame the body was loaded in. Without handle
    truth: the normal is the way the centre of the part's links' box moves as the joint starts to open (level), the
    grip where that direction leaves the box from its centre (the middle of its front), the bar horizontal across."""
    T = link_pose(client, body, link)
    if part.handle is not None:
        h = part.handle
        return T[:3, :3] @ h.centre + T[:3, 3], T[:3, :3] @ h.axis, T[:3, :3] @ h.normal
    lo, hi = _box(client, body, part_links(client, body, link))
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    normal = _opening_direction(client, body, link, T, centre)
    exit_at = min(h / abs(n) for h, n in zip(half, normal, strict=True) if abs(n) > 1e-9)
    return centre + exit_at * normal, np.cross(normal, [0.0, 0.0, 1.0]), normal


def _opening_direction(client: int, body: int, link: int, T: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The level unit direction `point` (on `link`, whose URDF frame is at `T`) moves as the link's joint value
    grows from here: along a prismatic joint's axis, or about a revolute joint's axis through the link's origin."""
    info = pb.getJointInfo(body, link, physicsClientId=client)
    axis = T[:3, :3] @ np.asarray(info[13], dtype=float)
    motion = axis if info[2] == pb.JOINT_PRISMATIC else np.cross(axis, point - T[:3, 3])
    motion[2] = 0.0
    return motion / np.linalg.norm(motion)


def _box(client: int, body: int, links: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    boxes = np.array([pb.getAABB(body, k, physicsClientId=client) for k in links])
    return boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)


ABOVE_M = 0.3  # the room above a grip is measured up to this far


@dataclass(frozen=True)
class PartGeometry:
    """A part closed, in its furniture's frame (metres): the `box` (lo, hi corners) of its links, its grip centre
    (`grip`), front `normal` and `room_above_m`: how far straight up from the grip the furniture's other shapes
    leave free (ABOVE_M: at least that)."""

    name: str
    kind: str
    box: tuple[np.ndarray, np.ndarray]
    grip: np.ndarray
    normal: np.ndarray
    room_above_m: float = ABOVE_M

    @property
    def front_centre(self) -> np.ndarray:
        """The middle of the box's face toward the front normal."""
        lo, hi = self.box
        centre = (lo + hi) / 2
        half = (hi - lo) / 2
        return centre + np.abs(self.normal) @ half * self.normal

    def corners(self) -> np.ndarray:
        lo, hi = self.box
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def measure_parts(furniture: Furniture) -> list[PartGeometry]:
    """Every part of `furniture` closed, measured in a throwaway PyBullet client."""
    client = pb.connect(pb.DIRECT)
    try:
        body = load_furniture(client, furniture, np.eye(4), 0.0)
        links = link_indices(client, body)
        out = []
        for part in furniture.parts:
            if part.link not in links:
                raise ValueError(f"{furniture.source}: part {part.name!r} names link {part.link!r}, which its URDF "
                                 f"{furniture.urdf} does not have")
            link = links[part.link]
            grip, _, normal = grip_frame(client, body, link, part)
            own = part_links(client, body, link)
            out.append(PartGeometry(part.name, part.kind, _box(client, body, own), grip, normal,
                                    _room_above(client, body, own, grip)))
        return out
    finally:
        pb.disconnect(client)


def _room_above(client: int, body: int, own: tuple[int, ...], point: np.ndarray) -> float:
    """How far straight up from `point` the shapes of `body` other than its links `own` leave free (m, at most
    ABOVE_M): the first such shape a ray up from it meets, past the part's own shapes."""
    top = (point + [0.0, 0.0, ABOVE_M]).tolist()
    start = np.asarray(point, dtype=float)
    while True:
        hit, link, fraction, position = pb.rayTest(start.tolist(), top, physicsClientId=client)[0][:4]
        if hit != body or fraction >= 1.0:
            return ABOVE_M
        if link not in own:
            return float(position[2] - point[2])
        start = np.array([point[0], point[1], position[2] + 1e-3])
