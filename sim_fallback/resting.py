"""What furniture parts rest on when closed, taken out of the collisions.

A drawer or door whose link touches something fixed while closed (a PartNet drawer front flush with its body's
bottom stands on the counter under it) would slide or swing along that surface. PyBullet solves such a contact,
whose normal the part's joint cannot move along, in a way that cuts the drive of anything pressing on the part
too: a gripper finger stalled on its handle pushes with only the force that moves the finger (~2 N of 40 N), not
with its motor's limit. A real part rides on its runners or hinges clear of what it stands on; its joint's limits
hold it closed and its mechanism (mechanisms.py) gives its friction. So a moving link and a fixed link (a static
shape, or a furniture link no joint moves) that touch when the parts are closed never collide.
"""

from __future__ import annotations

import pybullet as pb

REST_CONTACT_M = 0.0005  # closer than this with every part closed: the part rests on it


def moves(client: int, body: int, link: int) -> bool:
    """Whether a joint other than a fixed one lies between `link` and `body`'s base."""
    while link >= 0:
        info = pb.getJointInfo(body, link, physicsClientId=client)
        if info[2] != pb.JOINT_FIXED:
            return True
        link = info[16]
    return False


def release_resting_contacts(client: int, bodies: list[int]) -> list[tuple[int, int, int, int]]:
    """Stop collisions between every moving link of `bodies` and the fixed links of the other `bodies` it touches
    now (within REST_CONTACT_M); the pairs released, as (body, link, other body, other link)."""
    links = {body: range(-1, pb.getNumJoints(body, physicsClientId=client)) for body in bodies}
    moving = {(body, link) for body in bodies for link in links[body] if moves(client, body, link)}
    released: list[tuple[int, int, int, int]] = []
    for body, link in sorted(moving):
        for other in bodies:
            if other == body:
                continue
            near = pb.getClosestPoints(body, other, REST_CONTACT_M, linkIndexA=link, physicsClientId=client)
            for other_link in sorted({c[4] for c in near} - {k for b, k in moving if b == other}):
                pb.setCollisionFilterPair(body, other, link, other_link, 0, physicsClientId=client)
                released.append((body, link, other, other_link))
    return released
