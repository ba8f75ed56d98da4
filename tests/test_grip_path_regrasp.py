"""After a re-grasp following a slip, the hinge is fitted to the grip's path since the new grip only
(deploy/control/stages.py `estimate`, `_grip_path_axis`; `EpisodeState.grip_start` set by `hand.regrasp`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import deploy.control.stages as stages
from deploy.config import Config
from deploy.control.state import EpisodeState
from deploy.geometry.types import Axis, JointType, NoAxis

HINGE = np.array([0.9, 0.4, 0.66])  # a left door's hinge line, vertical; the closed front faces -x
UP = np.array([0.0, 0.0, 1.0])


def _arc(radius: float, from_deg: float, to_deg: float) -> list[np.ndarray]:
    """Tool poses (kept orientation) of a grip point `radius` from the hinge as the door turns between the angles."""
    poses = []
    for a in np.radians(np.linspace(from_deg, to_deg, 40)):
        T = np.eye(4)
        T[:3, 3] = HINGE + radius * np.array([-np.sin(a), -np.cos(a), 0.0])
        poses.append(T)
    return poses


def _episode(state: EpisodeState) -> SimpleNamespace:
    return SimpleNamespace(state=state, config=Config(), policy=SimpleNamespace(re_estimates=True),
                           observer=SimpleNamespace(latest_axis=lambda: NoAxis("not seen"), window=lambda: []),
                           tool=lambda: state.measured[-1])


def test_a_regrasp_further_along_the_tab_fits_the_hinge_to_the_new_grips_path_alone(monkeypatch):
    """The grip slid 6 cm along an edge pull toward the hinge before it slipped off at 15 deg; held again there,
    the door turned on to 35 deg. Both paths are arcs about the hinge but of radii 0.40 and 0.34 m: one circle fitted
    to both is no hinge. The fit to the new grip's path alone finds it and reads the turn since the re-grasp."""
    monkeypatch.setattr(stages, "_log_estimate", lambda episode, axis, source: None)
    first, second = _arc(0.40, 0.0, 15.0), _arc(0.34, 15.0, 35.0)
    prior = Axis(JointType.REVOLUTE, HINGE + np.array([0.0, 0.12, 0.0]), UP, confidence=0.0)  # 12 cm off
    state = EpisodeState(t0=0.0, joint=JointType.REVOLUTE, axis=prior, opened=np.radians(15.0),
                         opened_before=np.radians(15.0), p_grasp=second[0][:3, 3], across_force_n=20.0)
    state.measured = first + second
    state.grip_start = len(first)
    axis, source = stages.estimate(_episode(state), np.array([-1.0, 0.0, 0.0]))
    assert source.startswith("trajectory")
    off = axis.origin - HINGE
    assert np.linalg.norm(off - (off @ axis.direction) * axis.direction) < 0.01
    assert np.degrees(state.opened) == pytest.approx(35.0, abs=1.0)
