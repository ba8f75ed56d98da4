"""A parallel gripper's hold on a handle, as two friction-limited point contacts (not a weld).

When both fingers close on the handle, two point-to-point constraints join the hand and the handle at the grip
centre +-PAD_HALF_WIDTH_M along the bar (tool x). The pair leaves one rotation free, about the bar: the handle
turns in the fingers as a round bar does. Each constraint holds at most half the grip's friction force
(2 x friction coefficient x gripping force, two pads), so:
- pulled along the bar past that force, the bar slides through the fingers (the contacts move along it, and
  off its ends the grip is lost);
- pulled across the bar past that force (out of the fingers), the contacts drift; SLIP_DISTANCE_M away the grip
  breaks and the fingers close on nothing, as a real gripper's measured width shows.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

PAD_HALF_WIDTH_M = 0.01  # the two contacts lie this far either side of the grip centre along the bar
SLIDE_STEP_M = 0.001  # drift along the bar (or a twist) past this moves the contacts: the bar slides
SLIP_DISTANCE_M = 0.01  # drift across the bar past this breaks the grip


class Grip:
    """The hold of hand link `hand` (body `robot`) on link `handle` (body `cabinet`) with `force_limit_n` of
    friction in all; `update()` after every physics step applies sliding and reports a broken grip."""

    def __init__(self, client: int, robot: int, hand: int, cabinet: int, handle: int, centre: np.ndarray,
                 bar: np.ndarray, force_limit_n: float) -> None:
        self._client, self._robot, self._hand, self._cabinet, self._handle = client, robot, hand, cabinet, handle
        self.force_limit_n = float(force_limit_n)
        bar = np.asarray(bar, float) / np.linalg.norm(bar)
        anchors = [np.asarray(centre, float) + s * PAD_HALF_WIDTH_M * bar for s in (-1.0, 1.0)]
        self._on_hand = [self._local(robot, hand, p) for p in anchors]
        self._bar_in_hand = self._rotation(robot, hand).T @ bar
        self._ids: list[int] = []
        self._attach([self._local(cabinet, handle, p) for p in anchors])

    # --- state -------------------------------------------------------------------------------------------

    def update(self) -> bool:
        """Slide along the bar (or twist) when the friction gives; False when the grip broke (released)."""
        on_hand = [self._world(self._robot, self._hand, p) for p in self._on_hand]
        on_handle = [self._world(self._cabinet, self._handle, p) for p in self._on_handle]
        drift = [h - c for h, c in zip(on_hand, on_handle, strict=True)]
        bar = self._rotation(self._robot, self._hand) @ self._bar_in_hand
        mean = (drift[0] + drift[1]) / 2
        across = mean - (mean @ bar) * bar
        if np.linalg.norm(across) > SLIP_DISTANCE_M or not self._on_bar(np.mean(on_hand, axis=0), bar):
            self.release()
            return False
        if abs(mean @ bar) > SLIDE_STEP_M or np.linalg.norm(drift[0] - drift[1]) > SLIDE_STEP_M:
            self._detach()
            self._attach([self._local(self._cabinet, self._handle, h - across) for h in on_hand])
        return True

    def release(self) -> None:
        self._detach()

    # --- constraints -------------------------------------------------------------------------------------

    def _attach(self, on_handle: list[np.ndarray]) -> None:
        self._on_handle = on_handle
        for hand_point, handle_point in zip(self._on_hand, on_handle, strict=True):
            cid = pb.createConstraint(self._robot, self._hand, self._cabinet, self._handle, pb.JOINT_POINT2POINT,
                                      [0, 0, 0], parentFramePosition=hand_point.tolist(),
                                      childFramePosition=handle_point.tolist(), physicsClientId=self._client)
            pb.changeConstraint(cid, maxForce=self.force_limit_n / 2, physicsClientId=self._client)
            self._ids.append(cid)

    def _detach(self) -> None:
        for cid in self._ids:
            pb.removeConstraint(cid, physicsClientId=self._client)
        self._ids = []

    def _on_bar(self, centre: np.ndarray, bar: np.ndarray) -> bool:
        """Whether the grip centre is still within the handle's length (its bounding box along the bar)."""
        lo, hi = (np.asarray(v) for v in pb.getAABB(self._cabinet, self._handle, physicsClientId=self._client))
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        along = corners @ bar
        return along.min() - PAD_HALF_WIDTH_M <= centre @ bar <= along.max() + PAD_HALF_WIDTH_M

    # --- frames (PyBullet constraints live in the links' centre-of-mass frames) -----------------------------

    def _com(self, body: int, link: int) -> tuple[np.ndarray, np.ndarray]:
        state = pb.getLinkState(body, link, physicsClientId=self._client)
        return np.asarray(state[0]), np.asarray(pb.getMatrixFromQuaternion(state[1])).reshape(3, 3)

    def _rotation(self, body: int, link: int) -> np.ndarray:
        return self._com(body, link)[1]

    def _local(self, body: int, link: int, point: np.ndarray) -> np.ndarray:
        origin, rotation = self._com(body, link)
        return rotation.T @ (np.asarray(point, float) - origin)

    def _world(self, body: int, link: int, local: np.ndarray) -> np.ndarray:
        origin, rotation = self._com(body, link)
        return origin + rotation @ local
