"""A user's pixel on a handle, on synthetic D415 frames: a bar or a knob standing out of a drawer's front is taken
to mean that drawer, and the front is looked for from beside the handle; a counter's edge standing out over a
drawer is no handle."""

from __future__ import annotations

import numpy as np
import pytest

from deploy.perception.base import Pointer
from deploy.perception.handle_pixel import behind_handle
from deploy.perception.pointing import point_at
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
FRONT_M, WALL_M = 1.2, 1.6  # straight ahead: a pixel is 2 mm on the front
DRAWER = (slice(200, 280), slice(160, 480))  # 0.16 x 0.64 m
BAR = (slice(226, 232), slice(200, 440))  # 12 mm thick, 0.48 m long, 3 cm proud, 5 cm under the top
KNOB = (slice(237, 250), slice(314, 327))  # 26 mm across
WOOD, METAL = (150, 100, 60), (185, 185, 190)


def _frame(handle: tuple[slice, slice], counter: bool = False) -> Frame:
    """A drawer before a pale wall, its `handle` 3 cm proud of it; with `counter`, a counter top's 4 cm edge
    standing 3 cm out over the drawer's top and the top behind it, seen level (no surface above the edge)."""
    depth = np.full((480, 640), WALL_M, np.float32)
    color = np.full((480, 640, 3), 210, np.uint8)
    depth[DRAWER], color[DRAWER] = FRONT_M, WOOD
    depth[handle], color[handle] = FRONT_M - 0.03, METAL
    if counter:
        depth[180:200, 100:540], color[180:200, 100:540] = FRONT_M - 0.03, (230, 230, 225)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


@pytest.mark.parametrize("handle, pixel", [(BAR, (320, 229)), (BAR, (430, 227)), (KNOB, (320, 243))])
def test_a_pixel_on_a_handle_means_the_front_behind_it(handle, pixel):
    """The pixel lies on the handle, not on the front: its front is found from beside it, with that handle (before:
    the rectangle grew from the handle's cells and was refused as a narrow band)."""
    frame = _frame(handle)
    u, v = behind_handle(frame, np.zeros((480, 640), bool), *pixel)
    assert frame.depth_m[v, u] == FRONT_M and tuple(frame.color[v, u]) == WOOD
    found = point_at(frame, np.zeros((480, 640), bool), Pointer(*pixel))
    assert found.front.width_m == pytest.approx(0.64, abs=0.02)
    assert found.front.height_m == pytest.approx(0.16, abs=0.02)
    rows, cols = handle
    u, v = (cols.start + cols.stop - 1) / 2, (rows.start + rows.stop - 1) / 2  # the handle's centre pixel
    right, below = FRONT_M * (u - K.cx) / K.fx, FRONT_M * (v - K.cy) / K.fy  # base y is left, z up
    assert abs(found.handle.centre[1] + right) < 0.02 and abs(found.handle.centre[2] + below) < 0.02


@pytest.mark.parametrize("pixel", [(320, 250), (320, 190)])
def test_a_pixel_on_the_front_or_on_a_counters_edge_stays(pixel):
    """On the front itself, or on a counter's edge standing out over the drawer (the front's surface lies below it
    only), the pixel is the user's."""
    frame = _frame(BAR, counter=True)
    assert behind_handle(frame, np.zeros((480, 640), bool), *pixel) == pixel
