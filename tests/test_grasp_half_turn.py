"""A grasp is planned as found or, where that carries a more wanted pull, turned half a turn about its approach
(deploy/control/grasp.py `pregrasp_either_way`)."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.control.grasp import HALF_TURN, pregrasp_configuration, pregrasp_either_way, pull_poses
from drivers.arm.grasping import grasp_pose
from drivers.arm.motion import arc_path
from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config
from drivers.errors import ArmError

# A left door facing the robot 21 deg off its x axis, a horizontal bar 0.78 m out and 0.28 m to the left, its hinge
# 0.37 m farther left: held as found (tool x to the tool's left), the Panda's last joint starts 0.8 rad off its limit
# and carries 15 deg of the door's arc only; turned half a turn, the grasp carries its 45 deg.
NORMAL = np.array([-0.9346, -0.3557, 0.0]) / np.hypot(0.9346, 0.3557)
GRIP = np.array([0.716, 0.274, 0.641])  # the tool frame 1 cm past it, 0.725 m out
HINGE, UP_AXIS = np.array([0.625, 0.591, 0.639]), np.array([0.0, 0.0, -1.0])


@pytest.fixture(scope="module")
def panda():
    config = load_robot_config(PANDA_SIM_CONFIG)
    return config.kinematics(), np.array(config.q_ready)


def _arcs(T: np.ndarray, turn: bool) -> list[list[np.ndarray]]:
    return [pull_poses(arc_path(T, HINGE, UP_AXIS, turn=turn), np.radians(a), np.radians(5)) for a in (45, 30, 15)]


def test_the_grasp_turned_half_a_turn_keeps_the_wrist_off_its_limit_through_the_doors_turn(panda):
    kin, q_ready = panda
    bar = np.cross([0.0, 0.0, 1.0], NORMAL)
    T = grasp_pose(GRIP, NORMAL, bar / np.linalg.norm(bar))
    q_found = pregrasp_configuration(kin, q_ready, T, _arcs(T, False), 0.1)
    assert q_found[6] > kin.q_max[6] - 1.0  # as found, the wrist starts near its upper limit
    assert pregrasp_either_way(kin, q_ready, T, lambda P: _arcs(P, False)[2:], 0.1)[0] is T  # equals: as found
    T_held, q = pregrasp_either_way(kin, q_ready, T, lambda P: _arcs(P, False), 0.1)
    assert np.allclose(T_held, T @ HALF_TURN)
    assert abs(q[6]) < 1.5
    turned = _arcs(T_held, True)[1]  # the door's turn, the tool turning with it (a step that keeps the hand off it)
    kin.solve_path([T_held, *turned], kin.ik(T_held, q), restarts=0)
    with pytest.raises(ArmError):  # as found, the same turn takes the wrist past its limit
        kin.solve_path([T, *_arcs(T, True)[1]], kin.ik(T, q_found), restarts=0)
