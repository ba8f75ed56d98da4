"""A thin front seen on a synthetic D415 frame (straight ahead, no simulator): a plane fitted a step off the front at
the pixel (the refined fit joining a desk's thin drawer and the faces standing out above it) is moved onto the
front's own surface."""

from __future__ import annotations

import numpy as np
import pytest

import deploy.perception.front as front_module
from deploy.perception.front import find_front
from deploy.perception.plane_view import D415, NOISE_SIGMAS, QUANTUM_M, PlaneFrame
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
DEPTH_M = 1.0  # straight ahead: a pixel is 1.7 mm on the front
PX_M = DEPTH_M / K.fx
T = np.eye(4)
T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x


def _desk() -> Frame:
    """A drawer front 6 cm tall and 30 cm wide (rows 220-256, columns 230-410) 1 m ahead, under a slab standing 6 cm
    out of it, a wall 1.6 m away below and beside."""
    depth = np.full((480, 640), 1.6, np.float32)
    color = np.full((480, 640, 3), 200, np.uint8)
    depth[180:220], color[180:220] = DEPTH_M - 0.06, (120, 90, 50)
    drawer = (slice(220, 256), slice(230, 410))
    depth[drawer], color[drawer] = DEPTH_M, (150, 110, 60)
    return Frame(0, 0.0, color, depth, K, T)


def test_a_plane_a_step_off_a_thin_front_and_turned_from_it_is_moved_onto_it(monkeypatch):
    """The plane at the pixel runs twice the noise in front of the drawer there and is turned 2.5 deg from it:
    the front's rectangle is the drawer's (before: it collapsed at the pixel, a narrow band of 0.00 x 0.00 m)."""
    tolerance = NOISE_SIGMAS * float(D415.sigma_m(DEPTH_M, K.fx)) + QUANTUM_M / 2
    turn = np.radians(2.5)
    normal = np.array([-np.cos(turn), np.sin(turn), 0.0])
    origin = np.array([DEPTH_M - 2 * tolerance, 0.0, (240 - 238) * PX_M])  # pixel (320, 238)
    plane = PlaneFrame.facing(origin, normal, T[:3, 3])
    monkeypatch.setattr(front_module, "front_plane", lambda *args: (plane, DEPTH_M))
    front = find_front(_desk(), np.zeros((480, 640), bool), 320, 238)
    assert front.width_m == pytest.approx(180 * PX_M, abs=0.02)
    assert front.height_m == pytest.approx(36 * PX_M, abs=0.01)
    assert abs(front.plane.normal @ np.array([-1.0, 0.0, 0.0])) > np.cos(np.radians(0.5))

