"""The wrench the tool applies, from the joint torques an arm measures (no force sensor).

At rest or moving slowly the joint torques balance gravity and the contact: tau = g(q) + J(q)^T w, with `w` =
[force; moment] the tool applies to what it holds (N, N m; base-aligned axes at the tool origin, the frame of
`Kinematics.jacobian`). So w = (J^T)^+ (tau - g(q)): Pinocchio's gravity torques of the arm's model and a damped
pseudo-inverse (least squares on a 7-joint arm, exact on a 6-joint one). Inertial and friction torques are not
modelled: they are what the low-pass filter is for (noise figures: docs/benchmarks.md).

Torques measured from motor current carry an offset of their own (a few percent of each motor's peak torque): at rest
touching nothing the arm still reads tau - g(q) = offset, which the tool's image of moves as the arm does. So the
offset is measured in joint space, at rest and free (`torque_offset`), and subtracted from every reading.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from drivers.arm.base import ArmState
from drivers.arm.kinematics import Kinematics

PINV_DAMPING = 1e-4  # (J J^T + lambda I)^-1: bounded near singularities, negligible elsewhere
TIME_CONSTANT_S = 0.02  # default low-pass filter (about 8 Hz); robot configs set their own ([compliance])


class WrenchEstimator:
    """The tool's wrench from successive arm states, low-pass filtered (first order, `time_constant_s`).

    `update(state)` returns the filtered wrench (6,), or None when the arm measures no torques; `force` and
    `force_n` are the latest filtered force vector (N) and its magnitude; `reset()` starts the filter over, `start()`
    starts it at the mean of readings taken at rest. `offset`: the joint torques' own offset (N m per joint,
    `torque_offset`), subtracted from every reading (None: none).
    """

    def __init__(self, kin: Kinematics, time_constant_s: float = TIME_CONSTANT_S,
                 offset: Sequence[float] | None = None) -> None:
        if not time_constant_s >= 0:
            raise ValueError(f"wrench filter time constant must be 0 s or more, got {time_constant_s}")
        self.kin = kin
        self.time_constant_s = float(time_constant_s)
        self.offset = np.zeros(kin.model.nv) if offset is None else np.asarray(offset, float)
        self._data = kin.model.createData()
        self.wrench: np.ndarray | None = None
        self._t: float | None = None

    def reset(self) -> None:
        self.wrench, self._t = None, None

    def raw(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The unfiltered wrench (6,) at joints q with measured torques tau (N m)."""
        q = np.asarray(q, float)
        external = np.asarray(tau, float) - self.offset - pin.computeGeneralizedGravity(self.kin.model, self._data, q)
        J = self.kin.jacobian(q)
        return np.linalg.solve(J @ J.T + PINV_DAMPING * np.eye(6), J @ external)

    def start(self, states: Sequence[ArmState]) -> np.ndarray | None:
        """Start the filter over at the mean unfiltered wrench of `states`, measured at rest: one reading is as
        noisy as the measured torques, the mean of n readings sqrt(n) times less. None without measured torques."""
        measured = [s for s in states if s.tau is not None]
        if not measured:
            self.reset()
            return None
        self.wrench = np.mean([self.raw(s.q, s.tau) for s in measured], axis=0)
        self._t = measured[-1].t
        return self.wrench.copy()

    def update(self, state: ArmState) -> np.ndarray | None:
        """Fold in one measured state; the filtered wrench (None without measured torques)."""
        if state.tau is None:
            return None
        w = self.raw(state.q, state.tau)
        if self.wrench is None or self._t is None:
            self.wrench = w
        else:
            dt = max(state.t - self._t, 0.0)
            alpha = 1.0 if self.time_constant_s == 0 else dt / (self.time_constant_s + dt)
            self.wrench = self.wrench + alpha * (w - self.wrench)
        self._t = state.t
        return self.wrench.copy()

    @property
    def force(self) -> np.ndarray:
        """The latest filtered force the tool applies (N, base axes); zeros before any torque was measured."""
        return np.zeros(3) if self.wrench is None else self.wrench[:3].copy()

    @property
    def force_n(self) -> float:
        return float(np.linalg.norm(self.force))


def torque_offset(kin: Kinematics, states: Sequence[ArmState]) -> np.ndarray | None:
    """The joint torques' own offset (N m per joint): the mean of tau - g(q) over `states` measured at rest with the
    tool touching nothing. None when the arm measures no torques."""
    measured = [s for s in states if s.tau is not None]
    if not measured:
        return None
    data = kin.model.createData()
    return np.mean([s.tau - pin.computeGeneralizedGravity(kin.model, data, np.asarray(s.q, float))
                    for s in measured], axis=0)
