"""The first frame's static scene, and the moving part as what left it.

A fixed camera (on a tripod or on the robot's base) sees the same static surfaces in every frame; a part that opens
comes out in front of them. The first frame's depth is kept per pixel as the nearest surface within EDGE_REACH_PX
(a stereo depth pixel may take its value from any surface its matching window covers: widened edges and flying
pixels). A later pixel has left the static scene when its depth is nearer than that by more than the tolerance: the
difference of two D415 readings, NOISE_SIGMAS standard deviations of it, plus one depth unit. So:
- neighbours, the counter, the wall and the floor, which do not move, never leave it;
- the inside a door reveals lies behind the first frame's surfaces: static;
- pixels without depth in a later frame (holes, IR shadows, the arm's pixels that the self-filter removed) are
  unknown, neither static nor moving; where the first frame had no depth (an IR shadow, a dark patch, the arm, nothing
  in range) the static scene is the nearest surface on the hole's rim: what later stands in front of that has left it.
What left it counts as the moving part only inside the opening region (where the target part can be while it opens:
its front's outline swept out to how far an opening reaches), inside the frame's object mask (which keeps the arm's
pixels out), and in pieces larger than a stereo matching window (a noise excursion spreads over one window, a part
covers many): the moving part's own outlier filter, the same at every distance. The camera must not move: the
comparison is pixel by pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from deploy.errors import PerceptionError
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.types import Box

EDGE_REACH_PX = 3  # a D415 pixel's depth can come from a surface this far away (its matching window, at 640x480)
STEREO_BASELINE_M = 0.055  # the D415's infrared cameras' baseline
SUBPIXEL_RMS_PX = 0.08  # the D415's disparity noise (Intel's typical subpixel RMS): sigma_z = z^2 * this / (fx * b)
NOISE_SIGMAS = 4.0  # a static pixel reads nearer than its first reading by this many sigmas of the difference
# (two independent readings: sqrt(2) sigma_z) about 3 times in 100 000
DEPTH_UNIT_M = 0.001  # the D415's default depth unit (its quantisation)
REGION_MARGIN_M = 0.03  # the opening region's outline grows by this: a field calibration's error at 1-2 m
# (5 mm and 0.5 deg: up to 2 cm) and the front's edge as the stereo matching widens it
BEHIND_FRONT_M = 0.05  # a door's hinge-side edge swings this far behind its front (front thickness and margin)
SAME_POSE_M = 1e-4  # camera poses closer than this (m, and rad) are the same fixed camera


@dataclass(frozen=True)
class StaticScene:
    """The first frame as static surfaces, on every `step`-th pixel: `near_m` the nearest depth within EDGE_REACH_PX
    (holes filled from their rim), `tolerance_m` how much nearer a later reading must be to have left it, `K` the
    intrinsics of the reduced image and `T_base_camera` the camera's pose (None: points stay in the camera frame)."""

    near_m: np.ndarray
    tolerance_m: np.ndarray
    step: int
    K: np.ndarray
    T_base_camera: np.ndarray | None

    def check_view(self, depth_m: np.ndarray, T_base_camera: np.ndarray | None) -> None:
        """PerceptionError unless `depth_m` comes from the same fixed camera as the first frame."""
        shape = depth_m[::self.step, ::self.step].shape
        if shape != self.near_m.shape:
            raise PerceptionError(f"the depth image changed size ({depth_m.shape[1]}x{depth_m.shape[0]}) after the "
                                  "first frame: the static scene is compared pixel by pixel; keep the stream's "
                                  "resolution for the whole episode")
        if (T_base_camera is None) != (self.T_base_camera is None) or (
                T_base_camera is not None and not _same_pose(T_base_camera, self.T_base_camera)):
            raise PerceptionError("the camera moved after the first frame (its pose changed): the static-scene "
                                  "moving part needs a fixed camera (a tripod or the robot's base); with a camera on "
                                  "the hand use `[geometry] moving_part = \"box\"`")


def static_scene(depth_m: np.ndarray, K: np.ndarray, step: int = 2, T_base_camera: np.ndarray | None = None
                 ) -> StaticScene:
    """The static scene of a first frame's (H, W) depth (m, 0 = none), with pinhole matrix `K`, kept on every
    `step`-th pixel."""
    depth = np.asarray(depth_m, np.float32)
    far = np.where(np.isfinite(depth) & (depth > 0), depth, np.inf).astype(np.float32)
    window = np.ones((2 * EDGE_REACH_PX + 1, 2 * EDGE_REACH_PX + 1), np.uint8)
    near = _fill_holes(cv2.erode(far, window, borderType=cv2.BORDER_REPLICATE)[::step, ::step])
    K_step = np.diag([1.0 / step, 1.0 / step, 1.0]) @ np.asarray(K, float)
    return StaticScene(near, tolerance_m(near, float(np.asarray(K)[0, 0])), step, K_step,
                       None if T_base_camera is None else np.array(T_base_camera, float))


def tolerance_m(depth_m: np.ndarray, fx: float) -> np.ndarray:
    """How much nearer than a static reading at `depth_m` a later one must be to have left it (m)."""
    sigma = np.square(depth_m) * SUBPIXEL_RMS_PX / (fx * STEREO_BASELINE_M)
    return (NOISE_SIGMAS * np.sqrt(2.0) * sigma + DEPTH_UNIT_M).astype(np.float32)


def left_static(scene: StaticScene, depth_m: np.ndarray) -> np.ndarray:
    """(h, w) bool on the reduced image: the pixels of a later (H, W) depth that stand in front of the static scene."""
    depth = np.asarray(depth_m)[::scene.step, ::scene.step]
    return (depth > 0) & (depth < scene.near_m - scene.tolerance_m)


def opening_region(front: Box, outward: np.ndarray, reach_m: float, behind_m: float = BEHIND_FRONT_M,
                   margin_m: float = REGION_MARGIN_M) -> Box:
    """Where a part can be while it opens: the box `front` (a front's, or a whole body's) with outward normal
    `outward`, its outline grown by `margin_m`, reaching from `behind_m` behind its back to `reach_m` out of its
    front face (a drawer's travel; a door swings out to its width)."""
    outward = np.asarray(outward, float) / np.linalg.norm(outward)
    k = int(np.argmax(np.abs(front.rotation.T @ outward)))
    extent = front.extent + 2 * margin_m
    extent[k] = front.extent[k] + reach_m + behind_m
    shift = np.sign(front.rotation[:, k] @ outward) * (reach_m - behind_m) / 2
    return Box(front.center + shift * front.rotation[:, k], front.rotation, extent)


def opening_reach_m(front: Box, outward: np.ndarray, drawer_reach_m: float) -> float:
    """How far a part may come out of `front` (outward normal `outward`) while it opens: `drawer_reach_m` (a
    drawer's travel), or the front's width if larger (a door swings out that far)."""
    k = int(np.argmax(np.abs(front.rotation.T @ np.asarray(outward, float))))
    across = [float(front.extent[i]) for i in range(3) if i != k and abs(front.rotation[2, i]) < 0.5]
    return max([drawer_reach_m, *across])


def moving_pixels(scene: StaticScene, depth_m: np.ndarray, region: Box, allowed: np.ndarray | None = None,
                  depth_range_m: tuple[float, float] = (0.0, np.inf)) -> tuple[np.ndarray, np.ndarray]:
    """The moving part of a later frame: the (h, w) bool pixels of the reduced image and their (N, 3) points (base
    frame with a pose), row-major. A pixel counts when its depth is within `depth_range_m` and left the static scene,
    it lies in `allowed` (an (H, W) object mask, None: anywhere) and its point in `region`, and it belongs to a
    connected piece of such pixels larger than a stereo matching window."""
    candidates = left_static(scene, depth_m)
    if allowed is not None:
        candidates &= np.asarray(allowed, bool)[::scene.step, ::scene.step]
    depth = np.asarray(depth_m)[::scene.step, ::scene.step]
    candidates &= (depth >= depth_range_m[0]) & (depth <= depth_range_m[1])
    points = depth_to_points(depth, scene.K, mask=candidates, T_base_camera=scene.T_base_camera)
    rows, cols = np.nonzero(candidates)
    inside = region.contains(points)
    pixels = np.zeros(candidates.shape, bool)
    pixels[rows[inside], cols[inside]] = True
    pixels = _without_specks(pixels, scene.step)
    return pixels, points[pixels[rows, cols]]


def _without_specks(pixels: np.ndarray, step: int) -> np.ndarray:
    """`pixels` without the 8-connected pieces smaller than a stereo matching window (2 EDGE_REACH_PX + 1 pixels
    square at full resolution) on the image reduced by `step`."""
    window = int(np.ceil((2 * EDGE_REACH_PX + 1) / step))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(pixels.astype(np.uint8), connectivity=8)
    large = stats[:, cv2.CC_STAT_AREA] >= window * window
    large[0] = False
    return large[labels]


def _fill_holes(near: np.ndarray) -> np.ndarray:
    """`near` (inf in holes) with each hole (8-connected) set to the smallest depth on its rim: for a plane, and for
    any surface whose nearest point over the hole lies on its rim, nothing the hole hides is nearer. 0 where a hole
    has no rim (an image without depth)."""
    holes = ~np.isfinite(near)
    if not holes.any():
        return near
    count, labels = cv2.connectedComponents(holes.astype(np.uint8), connectivity=8)
    beside = cv2.dilate(labels.astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.int64)  # a hole's label
    rim = ~holes & (beside > 0)
    smallest = np.full(count, np.inf, np.float32)
    np.minimum.at(smallest, beside[rim], near[rim])
    smallest[~np.isfinite(smallest)] = 0.0
    filled = near.copy()
    filled[holes] = smallest[labels[holes]]
    return filled


def _same_pose(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return bool(np.abs(a[:3, 3] - b[:3, 3]).max() <= SAME_POSE_M and np.abs(a[:3, :3] - b[:3, :3]).max() <= SAME_POSE_M)
