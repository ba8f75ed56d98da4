"""Which way round a handle is held again after a slip (deploy.control.hand.held_way_round)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deploy.control.grasp import HALF_TURN
from deploy.control.hand import held_way_round
from drivers.arm.grasping import grasp_pose

NORMAL = np.array([-0.875, 0.485, 0.0])  # a front turned toward the robot


@pytest.mark.parametrize("planned_turned", [False, True])
def test_a_handle_is_held_again_the_way_round_the_hand_held_it(planned_turned):
    T_found = grasp_pose(np.array([0.66, -0.28, 0.64]), NORMAL, np.array([0.485, 0.875, 0.0]))
    T_held = grasp_pose(np.array([0.68, -0.26, 0.64]), NORMAL, np.array([0.485, 0.875, 0.0]))
    T_held[:3, :3] = Rotation.from_rotvec([0.0, 0.0, 0.15]).as_matrix() @ T_held[:3, :3]  # the handle turned a bit
    if planned_turned:  # the first grasp was turned half a turn to keep the wrist's last joint off its limit
        T_held = T_held @ HALF_TURN
    T = held_way_round(T_found, T_held)
    np.testing.assert_allclose(T[:3, 3], T_found[:3, 3])
    np.testing.assert_allclose(T[:3, 2], T_found[:3, 2])  # the same approach
    assert T[:3, 0] @ T_held[:3, 0] > 0.9  # the fingers as they were
