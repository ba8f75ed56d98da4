"""A pointer on a handle: a user who means a drawer or a door often points at its handle ("open this one"). A bar or
a knob stands out of its front, so the plane fitted around the pixel is the front's and the pixel lies off it; the
part meant is the front behind the handle, and the front is looked for from a pixel of it just beside the handle.

A pure function of one frame (colour, depth, intrinsics, the calibrated camera pose), the arm's pixels and the user's
pixel.
"""

from __future__ import annotations

import cv2
import numpy as np

from deploy.errors import PointerError
from deploy.geometry.cloud import depth_to_points
from deploy.perception.front import FRONT_TILT_DEG, seed_plane, tilt_deg
from deploy.perception.front_extent import COLOUR_DELTA_E, colour_distance
from deploy.perception.handle_blobs import MAX_ACROSS_M, MAX_STANDOFF_M, MIN_RELIEF_M
from deploy.perception.plane_view import D415, NOISE_SIGMAS, QUANTUM_M
from drivers.camera.base import Frame

SURFACE_RUN_M = 0.01  # the front resumes past the handle where this long a run of pixels lies on its plane (one of
# the handle's noisy pixels may fall within the plane's noise band)
BESIDE_M = 0.06  # the front's run past the handle is followed this far at most
ON, PROUD, UNSEEN, OFF = 0, 1, 2, 3  # a pixel on the plane, a handle's relief out of it, without depth, elsewhere


def behind_handle(frame: Frame, robot: np.ndarray, u: int, v: int) -> tuple[int, int]:
    """The pixel to look for the front from when pixel (u, v) lies on a handle: one beside it on the front; else
    (u, v). The pixel is on a handle when it stands out of the plane fitted around it (`seed_plane`: the front's, a
    handle is thin) by MIN_RELIEF_M and the noise up to MAX_STANDOFF_M, or has no depth next to such pixels, and the
    plane's surface resumes on two opposite sides within MAX_ACROSS_M (a bar across its length, a knob every way; a
    counter's edge has its top above it). Of the two opposite sides nearest each other (across a bar, not along
    it), the pixel is taken in the middle of the longer stretch of the front's colour (`_front_stretch`)."""
    try:
        point, normal, depth = seed_plane(frame, robot, u, v)
    except PointerError:
        return u, v
    if tilt_deg(normal) > FRONT_TILT_DEG or robot[v, u]:
        return u, v
    state, px_m = _pixel_states(frame, robot, point, normal, depth, (u, v))
    walks = {d: _crossing(state, (u, v), d, px_m) for d in ((-1, 0), (1, 0), (0, -1), (0, 1))}
    pairs = [(d, e) for d, e in (((-1, 0), (1, 0)), ((0, -1), (0, 1))) if walks[d] and walks[e]]
    if not pairs:
        return u, v
    sides = min(pairs, key=lambda p: walks[p[0]][0] + walks[p[1]][0])
    if state[v, u] != PROUD and not any(walks[d][2] for d in sides) or any(walks[d][0] == 0 for d in sides):
        return u, v
    stretches = {d: _front_stretch(frame, state, (u, v), d, walks[d][:2]) for d in sides}
    side = max(sides, key=lambda d: (stretches[d][1] - stretches[d][0], -stretches[d][0]))
    step = sum(stretches[side]) // 2
    return u + side[1] * step, v + side[0] * step


def _pixel_states(frame: Frame, robot: np.ndarray, point: np.ndarray, normal: np.ndarray, depth: float,
                  pixel: tuple[int, int]) -> tuple[np.ndarray, float]:
    """Each pixel's state (H, W) around `pixel` (within the crossing's and the run's reach; UNSEEN past it and on the
    arm): ON the plane (within the D415's noise), PROUD of it (a handle's relief), UNSEEN (no depth) or OFF; and a
    pixel's size at the plane (m)."""
    px_m = depth / frame.intrinsics.fx
    reach = int(np.ceil((MAX_ACROSS_M + BESIDE_M) / px_m))
    u, v = pixel
    mask = np.zeros(frame.depth_m.shape, bool)
    mask[max(v - reach, 0):v + reach + 1, max(u - reach, 0):u + reach + 1] = True
    mask &= ~robot & (frame.depth_m > 0)
    points = depth_to_points(frame.depth_m, frame.intrinsics.K, mask, frame.T_base_camera)
    camera = np.asarray(frame.T_base_camera, float)[:3, 3]
    offset = (points - point) @ (normal if (camera - point) @ normal >= 0 else -normal)  # toward the camera
    tolerance = NOISE_SIGMAS * D415.sigma_m(np.linalg.norm(points - camera, axis=1), frame.intrinsics.fx) + QUANTUM_M
    state = np.full(frame.depth_m.shape, UNSEEN, np.int8)
    state[mask] = np.where(np.abs(offset) <= tolerance, ON, np.where(  # the mask's pixels in row-major order
        (offset > np.maximum(tolerance, MIN_RELIEF_M)) & (offset < MAX_STANDOFF_M), PROUD, OFF))
    return state, px_m


def _line(shape: tuple[int, ...], pixel: tuple[int, int], direction: tuple[int, int], n: int) -> tuple:
    """(rows, cols) of the first `n` pixels from `pixel` along `direction` (it included) inside the image."""
    steps = np.arange(n)
    rows, cols = pixel[1] + direction[0] * steps, pixel[0] + direction[1] * steps
    inside = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
    return rows[inside], cols[inside]


def _crossing(state: np.ndarray, pixel: tuple[int, int], direction: tuple[int, int],
              px_m: float) -> tuple[int, int, int] | None:
    """From `pixel` along `direction`: (the steps to where the plane's surface resumes for SURFACE_RUN_M, the length
    of that run up to BESIDE_M, how many PROUD pixels lie before it); None when a pixel OFF the plane comes first or
    the surface does not resume within MAX_ACROSS_M."""
    need = max(int(round(SURFACE_RUN_M / px_m)), 1)
    line = state[_line(state.shape, pixel, direction, int((MAX_ACROSS_M + BESIDE_M) / px_m))]
    on = np.r_[line == ON, False].astype(int)  # ends off the surface
    for i in range(min(int(MAX_ACROSS_M / px_m), len(line) - need) + 1):
        if on[i:i + need].all():
            run = min(int(np.argmin(on[i:])), int(BESIDE_M / px_m))
            return i, run, int(np.count_nonzero(line[:i] == PROUD))
        if line[i] == OFF:
            return None
    return None


def _front_stretch(frame: Frame, state: np.ndarray, pixel: tuple[int, int], direction: tuple[int, int],
                   walk: tuple[int, int]) -> tuple[int, int]:
    """[first, last) steps from `pixel` along `direction` of the longest stretch, within the plane's run past the
    handle (`walk`: its start and length), whose colour is the front's: within COLOUR_DELTA_E of the median colour
    of the plane's pixels around (a handle's shadow on the front is darker)."""
    lab = cv2.cvtColor(frame.color, cv2.COLOR_RGB2LAB).astype(np.float32)
    reference = np.median(lab[state == ON], axis=0)
    start, run = walk
    rows, cols = _line(state.shape, pixel, direction, start + run)
    same = np.r_[colour_distance(lab[rows[start:], cols[start:]], reference) <= COLOUR_DELTA_E, False]
    best, first = (start, start), None
    for i, ok in enumerate(same):
        if ok and first is None:
            first = i
        elif not ok and first is not None:
            best, first = max(best, (start + first, start + i), key=lambda b: b[1] - b[0]), None
    return best
