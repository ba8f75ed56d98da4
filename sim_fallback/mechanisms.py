"""How cabinet parts resist and close: seeded realistic `Mechanism`s, and their forces applied to PyBullet joints.

Coulomb friction is the joint's velocity motor (target velocity 0, at most the friction force: PyBullet ignores URDF
friction); stiction raises that limit while the part is at rest; damping is the joint's damping. Self-closing
springs, soft-close springs and magnetic catches push toward closed with a force applied on the part's link before
every physics step (`MechanismForces`, a `PhysicsClock` hook). A drawer stops at its end: its URDF limit.

Values (engineering estimates for kitchen hardware): drawers on runners need 5-20 N to start moving, a soft-close
drawer 10-25 N more over its last few cm; doors 1-3 N at the handle, a magnetic catch 3-8 N of break-away there;
a self-closing hinge holds a door shut and pulls it back from any angle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb

from sim_fallback.furniture import Mechanism, PartKind

AT_REST_M_S, AT_REST_RAD_S = 0.002, 0.01  # slower than this, a part sticks (stiction applies)
SHUT = 1e-4  # a joint value (m or rad) this near closed is shut


def random_mechanism(kind: PartKind, lever_m: float, rng: np.random.Generator) -> Mechanism:
    """A part's mechanism, drawn from `rng`. `lever_m`: a door's hinge-to-handle distance (forces at its handle are
    torques / lever_m); unused for drawers."""
    if kind == "drawer":
        friction, stiction = float(rng.uniform(5.0, 14.0)), float(rng.uniform(0.5, 5.0))
        soft = rng.random() < 0.5
        return Mechanism(friction=friction, damping=float(rng.uniform(3.0, 8.0)), stiction=stiction,
                         soft_close_range=float(rng.uniform(0.03, 0.06)) if soft else 0.0,
                         soft_close_force=float(rng.uniform(10.0, 25.0)) if soft else 0.0)
    friction, stiction = (float(rng.uniform(*r)) * lever_m for r in ((1.0, 3.0), (0.3, 1.5)))
    closing = rng.choice(["catch", "spring", "soft-close", "none"], p=[0.35, 0.2, 0.25, 0.2])
    held = friction + stiction
    return Mechanism(
        friction=friction, damping=float(rng.uniform(0.3, 1.2)), stiction=stiction,
        spring_preload=float(rng.uniform(1.5, 2.5)) * held if closing == "spring" else 0.0,
        spring_stiffness=float(rng.uniform(0.2, 1.0)) * held if closing == "spring" else 0.0,
        soft_close_range=float(np.radians(rng.uniform(15.0, 30.0))) if closing == "soft-close" else 0.0,
        soft_close_force=float(rng.uniform(1.5, 2.5)) * held if closing == "soft-close" else 0.0,
        catch_range=float(np.radians(rng.uniform(2.0, 5.0))) if closing == "catch" else 0.0,
        catch_force=float(rng.uniform(3.0, 8.0)) * lever_m if closing == "catch" else 0.0,
    )


def closing_force(m: Mechanism, value: float) -> float:
    """The force (N, or N m for a door) the mechanism pushes a part at joint `value` toward closed with."""
    force = 0.0
    if m.spring_preload or m.spring_stiffness:
        force += m.spring_preload + m.spring_stiffness * max(value, 0.0)
    if m.soft_close_force and value < m.soft_close_range:
        force += m.soft_close_force
    if m.catch_force and value < m.catch_range:
        force += m.catch_force * (1.0 - max(value, 0.0) / m.catch_range)
    return force


@dataclass(frozen=True)
class JointMechanism:
    """One part's joint in a loaded world: `body`, `joint` index (= its link's), prismatic or not, its unit axis
    in the world (a positive value opens along it), the `friction` in force (the scenario's condition applied) and
    its mechanism."""

    body: int
    joint: int
    prismatic: bool
    axis_world: np.ndarray
    friction: float
    mechanism: Mechanism


def set_friction(client: int, body: int, joint: int, force: float) -> None:
    """The joint's Coulomb friction (N or N m) as its velocity motor's force limit."""
    pb.setJointMotorControl2(body, joint, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=force,
                             physicsClientId=client)


class MechanismForces:
    """Applies every part's stiction and closing force; call `apply()` before each physics step (it is a
    `PhysicsClock` hook, and the world calls it once before the first step). Parts whose mechanism has neither
    cost nothing. A part at rest shut is held by its joint's motor with its friction, stiction and closing force
    (pulled open, it breaks away past their sum, as a catch does), with no force to apply each step."""

    def __init__(self, client: int, joints: list[JointMechanism]) -> None:
        self._client = client
        active = [j for j in joints if _active(j.mechanism)]
        self._bodies: dict[int, list[JointMechanism]] = {}
        for j in active:
            self._bodies.setdefault(j.body, []).append(j)
        self._hold = {(j.body, j.joint): j.friction for j in active}

    def apply(self) -> None:
        c = self._client
        for body, joints in self._bodies.items():
            states = pb.getJointStates(body, [j.joint for j in joints], physicsClientId=c)
            for j, (value, velocity, *_) in zip(joints, states, strict=True):
                at_rest = abs(velocity) < (AT_REST_M_S if j.prismatic else AT_REST_RAD_S)
                shut = at_rest and value <= SHUT
                self._hold_with(j, j.friction + (j.mechanism.stiction if at_rest else 0.0)
                                + (closing_force(j.mechanism, 0.0) if shut else 0.0))
                if not shut:
                    self._push(j, closing_force(j.mechanism, value))

    def _hold_with(self, j: JointMechanism, force: float) -> None:
        """The joint's motor resists up to `force` (set only when it changes)."""
        key = (j.body, j.joint)
        if force != self._hold[key]:
            set_friction(self._client, j.body, j.joint, force)
            self._hold[key] = force

    def _push(self, j: JointMechanism, force: float) -> None:
        if force == 0.0:
            return
        c, push = self._client, (-force * j.axis_world).tolist()
        if j.prismatic:
            centre = pb.getLinkState(j.body, j.joint, physicsClientId=c)[0]
            pb.applyExternalForce(j.body, j.joint, push, centre, pb.WORLD_FRAME, physicsClientId=c)
        else:
            pb.applyExternalTorque(j.body, j.joint, push, pb.WORLD_FRAME, physicsClientId=c)


def _active(m: Mechanism) -> bool:
    return bool(m.stiction or m.spring_preload or m.spring_stiffness or m.soft_close_force or m.catch_force)
