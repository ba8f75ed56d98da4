"""A parallel gripper's hold on whatever its two fingers close on, as friction-limited point contacts (not a weld).

What it holds: the body and link both fingers touch (`grasped_link`), whatever it is: a handle link, a door whose
link holds its handle, a knob, a neighbour's front.

How firmly: two rubber pads with friction coefficient mu, squeezed with the gripping force F, hold up to 2 mu F
against a pull. Where the pads touch is found from the geometry between the fingers (`ContactPatch`): along the
pads' width (the hand's x axis, a bar's length) the patch covers the whole pad on a bar, a few millimetres on a
round knob. Two point-to-point constraints join hand and object at the patch centre +- a quarter of its span along
x, each holding at most mu F (PyBullet bounds a constraint's force per world axis: along a diagonal it holds up to
sqrt(3) times more; the arm's own weight, which the solver shares with the constraints, then stays off the other
axes' friction). Together they resist a twist about the closing or the approach axis with up to
mu F x span / 2, the friction moment of a line contact under uniform pressure, and leave the rotation about x free
(a round bar turns in the fingers). So a knob turns in the fingers under a twist a bar holds, and a pad that spends
its friction on the twist has less left to hold the pull. The fingers' own contact friction must be off (the
simulated arm turns it off): the grip is the friction.

- Pulled along x past its friction, or twisted past it, the object slides or turns in the fingers: past
  SLIDE_STEP_M or TWIST_STEP_RAD the constraints are made again where the pads now are (PyBullet's force limit
  bounds a constraint's impulse, but its position correction still pulls a small drift back: moving the
  constraints is what lets the object go); a finger that no longer touches the object (slid off a bar's end)
  breaks the grip.
- Pulled across x in the pads' plane past it (out of the fingers), the contacts drift; SLIP_DISTANCE_M away the
  grip breaks and the fingers close on nothing, as a real gripper's measured width shows. Along the closing
  direction the pads' contacts push (not their friction): a drift that way moves the constraints, as the fingers
  centre what they hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb

PAD_HALF_WIDTH_M = 0.0088  # the Panda finger's pad, either side of the finger's centre along the hand's x
PAD_GIVE_M = 0.0005  # the rubber pad yields this deep under the grip: surface this close to the deepest point touches
PROBE_STEP_M = 0.0005  # the pad's width is probed at this spacing
SLIDE_STEP_M = 0.001  # drift along the bar past this moves the contacts: the object slides
TWIST_STEP_RAD = np.radians(1.0)  # a twist (not about the bar) past this moves the contacts: the object turns
SLIP_DISTANCE_M = 0.01  # drift across the bar in the pads' plane (out of the fingers) past this breaks the grip
LOST_CONTACT_STEPS = 12  # a finger off the object this many physics steps running (0.05 s) breaks the grip


def make_probe(client: int) -> int:
    """The collision shape a grip probes the pads' surroundings with (make one per physics client)."""
    return pb.createCollisionShape(pb.GEOM_SPHERE, radius=PROBE_STEP_M / 2, physicsClientId=client)


def grasped_link(client: int, robot: int, fingers: list[int]) -> tuple[int, int] | None:
    """The (body, link) every finger of `robot` touches (not the robot itself), the one pressed hardest when there
    are several; None when the fingers touch nothing in common."""
    force: dict[tuple[int, int], float] = {}
    common: set[tuple[int, int]] | None = None
    for finger in fingers:
        touched = set()
        for c in pb.getContactPoints(bodyA=robot, linkIndexA=finger, physicsClientId=client):
            if c[2] != robot:
                touched.add((c[2], c[4]))
                force[(c[2], c[4])] = force.get((c[2], c[4]), 0.0) + c[9]
        common = touched if common is None else common & touched
    if not common:
        return None
    return max(sorted(common), key=lambda pair: force[pair])


@dataclass(frozen=True)
class ContactPatch:
    """Where the pads touch an object: `centre` (world, m, midway between the pads) and `span_m`, the patch's
    length along `axis` (the hand's x, unit), the mean of the two pads'."""

    centre: np.ndarray
    axis: np.ndarray
    span_m: float


class Grip:
    """The hold of hand link `hand` (body `robot`, with `fingers`) on link `link` of body `body`: the pads' total
    friction `force_limit_n` (2 mu F); `probe` from `make_probe` (one per client). `update()` after every physics
    step slides or turns the contacts and reports a broken grip (False, released). ValueError when the fingers do
    not both touch that link (see `grasped_link`)."""

    def __init__(self, client: int, robot: int, hand: int, fingers: list[int], body: int, link: int,
                 force_limit_n: float, probe: int) -> None:
        self._client, self._robot, self._hand, self._fingers = client, robot, hand, list(fingers)
        self.body, self.link = body, link
        self.force_limit_n = float(force_limit_n)
        self._probe = probe
        self._ids: list[int] = []
        self._on_hand: list[np.ndarray] = []
        self._on_object: list[np.ndarray] = []
        self._lost_steps = 0
        self.span_m = 0.0
        patch = self.patch()
        if patch is None:
            self.release()
            raise ValueError(f"grip: the fingers do not both touch body {body} link {link}")
        self._attach(patch, np.zeros(3))

    # --- state -------------------------------------------------------------------------------------------

    def update(self) -> bool:
        """Slide along the bar or turn when the friction gives; False when the grip broke (released)."""
        on_hand = [self._world(self._robot, self._hand, p) for p in self._on_hand]
        on_object = [self._world(self.body, self.link, p) for p in self._on_object]
        drift = [h - c for h, c in zip(on_hand, on_object, strict=True)]
        hand = self._rotation(self._robot, self._hand)
        bar, closing = hand[:, 0], hand[:, 1]
        mean = (drift[0] + drift[1]) / 2
        out = mean - (mean @ bar) * bar - (mean @ closing) * closing  # in the pads' plane, across the bar
        touching = all(self._touches(f) for f in self._fingers)
        self._lost_steps = 0 if touching else self._lost_steps + 1
        if np.linalg.norm(out) > SLIP_DISTANCE_M or self._lost_steps >= LOST_CONTACT_STEPS:
            self.release()
            return False
        moved = max(abs(mean @ bar), abs(mean @ closing))  # along the bar, or pressed into a pad
        if moved > SLIDE_STEP_M or self._twist() > np.sin(TWIST_STEP_RAD):
            patch = self.patch() if touching else None
            if patch is not None:
                self._detach()
                self._attach(patch, out)
        return True

    def release(self) -> None:
        """Remove the constraints (idempotent)."""
        self._detach()

    def patch(self) -> ContactPatch | None:
        """The pads' contact patch on the object now; None when a finger does not touch it."""
        bar = self._rotation(self._robot, self._hand)[:, 0]
        centres, spans = [], []
        for finger in self._fingers:
            contacts = pb.getContactPoints(self._robot, self.body, finger, self.link, physicsClientId=self._client)
            if not contacts:
                return None
            on_pad = np.mean([c[5] for c in contacts], axis=0)  # on the finger's surface
            pad_centre = np.asarray(pb.getLinkState(self._robot, finger, physicsClientId=self._client)[4])
            offsets = np.arange(-PAD_HALF_WIDTH_M, PAD_HALF_WIDTH_M + 1e-9, PROBE_STEP_M)
            line = on_pad + np.outer(offsets + (pad_centre - on_pad) @ bar, bar)
            gaps = np.array([self._gap(p) for p in line])
            touches = gaps <= gaps.min() + PAD_GIVE_M
            centres.append(line[touches].mean(axis=0))
            spans.append(offsets[touches].max() - offsets[touches].min() + PROBE_STEP_M)
        return ContactPatch(np.mean(centres, axis=0), bar, float(np.mean(spans)))

    # --- constraints -------------------------------------------------------------------------------------

    def _attach(self, patch: ContactPatch, across: np.ndarray) -> None:
        """Constraints at the patch centre +- span / 4 along the bar; the object's ends `across` from the hand's."""
        self.span_m = patch.span_m
        self._rotation0 = self._relative_rotation()
        self._bar_in_hand = self._rotation(self._robot, self._hand).T @ patch.axis
        anchors = [patch.centre + s * patch.span_m / 4 * patch.axis for s in (-1.0, 1.0)]
        self._on_hand = [self._local(self._robot, self._hand, p) for p in anchors]
        self._on_object = [self._local(self.body, self.link, p - across) for p in anchors]
        for hand_point, object_point in zip(self._on_hand, self._on_object, strict=True):
            cid = pb.createConstraint(self._robot, self._hand, self.body, self.link, pb.JOINT_POINT2POINT,
                                      [0, 0, 0], parentFramePosition=hand_point.tolist(),
                                      childFramePosition=object_point.tolist(), physicsClientId=self._client)
            pb.changeConstraint(cid, maxForce=self.force_limit_n / 2, physicsClientId=self._client)
            self._ids.append(cid)

    def _twist(self) -> float:
        """The sine of how far the object has turned in the hand since the constraints were made, about any axis
        but the bar (about the bar it turns freely)."""
        turn = self._relative_rotation() @ self._rotation0.T  # in the hand frame
        axis_sin = 0.5 * np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]])
        bar = self._bar_in_hand
        return float(np.linalg.norm(axis_sin - (axis_sin @ bar) * bar))

    def _relative_rotation(self) -> np.ndarray:
        return self._rotation(self._robot, self._hand).T @ self._rotation(self.body, self.link)

    def _detach(self) -> None:
        for cid in self._ids:
            pb.removeConstraint(cid, physicsClientId=self._client)
        self._ids = []

    def _touches(self, finger: int) -> bool:
        return bool(pb.getContactPoints(self._robot, self.body, finger, self.link, physicsClientId=self._client))

    def _gap(self, point: np.ndarray) -> float:
        """Distance (m) from `point` to the object's surface, negative inside; large when nothing is near."""
        near = pb.getClosestPoints(bodyA=self.body, bodyB=-1, distance=0.01, linkIndexA=self.link,
                                   collisionShapeB=self._probe, collisionShapePositionB=point.tolist(),
                                   physicsClientId=self._client)
        return min((c[8] for c in near), default=np.inf) + PROBE_STEP_M / 2

    # --- frames (PyBullet constraints live in the links' centre-of-mass frames) -----------------------------

    def _com(self, body: int, link: int) -> tuple[np.ndarray, np.ndarray]:
        if link < 0:
            position, orientation = pb.getBasePositionAndOrientation(body, physicsClientId=self._client)
        else:
            position, orientation = pb.getLinkState(body, link, physicsClientId=self._client)[:2]
        return np.asarray(position), np.asarray(pb.getMatrixFromQuaternion(orientation)).reshape(3, 3)

    def _rotation(self, body: int, link: int) -> np.ndarray:
        return self._com(body, link)[1]

    def _local(self, body: int, link: int, point: np.ndarray) -> np.ndarray:
        origin, rotation = self._com(body, link)
        return rotation.T @ (np.asarray(point, float) - origin)

    def _world(self, body: int, link: int, local: np.ndarray) -> np.ndarray:
        origin, rotation = self._com(body, link)
        return origin + rotation @ local
