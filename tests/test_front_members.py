"""A stretch off a front's surface that runs on past both of its sides is a member across the furniture (a
counter's edge between an appliance on the counter and the cabinets under it), not a handle: the front ends there.
Synthetic D415 frames, the camera 2 m straight ahead (a pixel is 3.3 mm)."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.front import find_front
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
BOX_V, BOX_U = (120, 200), (220, 400)  # an appliance's front: 0.27 x 0.60 m, level with the cabinets' fronts


def _frame(band_u: tuple[int, int]) -> Frame:
    """The appliance before a wall 2.6 m away, on a counter whose edge (5 cm tall, 4 cm proud, another colour) runs
    over columns `band_u` above cabinet fronts of the appliance's grey."""
    depth = np.full((480, 640), 2.6, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    box = (slice(*BOX_V), slice(*BOX_U))
    depth[box], color[box] = 2.0, (120, 120, 120)
    cabinets = (slice(BOX_V[1], 420), slice(60, 580))
    depth[cabinets], color[cabinets] = 2.0, (124, 124, 124)
    edge = (slice(BOX_V[1], BOX_V[1] + 15), slice(*band_u))
    depth[edge], color[edge] = 1.96, (150, 100, 60)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


@pytest.mark.parametrize("band_u, below", [((60, 580), False), ((250, 370), True)])
def test_a_counters_edge_past_both_sides_of_a_front_ends_it_a_stretch_within_them_does_not(band_u, below):
    """The counter's edge runs past the appliance's sides: its front ends above it (before: the edge, narrower than
    a handle band, was crossed and the front ran on down the cabinets). A stretch ending within the front's sides
    (a handle's place) is crossed as before."""
    front = find_front(_frame(band_u), np.zeros((480, 640), bool), 310, 160)
    appliance_bottom_z = (K.cy - BOX_V[1]) * 2.0 / K.fy  # the base's z is up, the camera's rows go down
    assert (float(front.corners[:, 2].min()) < appliance_bottom_z - 0.05) == below
