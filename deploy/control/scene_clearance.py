"""A grasp whose approach and first pull keep clear of the scene the first frame showed: a counter's overhang, a
neighbour's handle or front, a wall beside the unit (deploy/geometry/clearance.py). The scene is the first frame's
depth (the arm's pixels removed) in the base frame, less the pointed front and its handle, which move with the
gripper; the grasps tried are the usual one, the one approaching level (no downward tilt), the one tilted up (from
under an overhang), all again with the fingers opened only as wide as the handle needs, into a recessed pull all of
these again going in less deep (the hand farther out of the front), and for a knob all of these turned a quarter;
after all of them, the same tilted steeply down (a low handle grasped from above)."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from deploy.control.grasp import Handle, grasp_pose
from deploy.control.state import EpisodeStop, StopReason
from deploy.geometry.clearance import (
    ToolBox,
    clearance,
    depth_behind,
    first_behind,
    first_contact,
    outside_box,
    parallel_gripper,
    standing_out,
)
from deploy.geometry.cloud import depth_to_points
from deploy.perception.handle import EDGE_BAND_M
from deploy.perception.handle_blobs import MAX_STANDOFF_M
from deploy.perception.pointing import PointedPart
from drivers.arm.grasping import FROM_ABOVE_RAD, GRASP_PITCH_RAD, pregrasp_pose
from drivers.camera.base import Frame

CLEARANCE_M = -0.005  # the gripper hits the scene where a scene point lies this deep inside it: nearer ones are
# within the calibration's error (5 mm) and the depth's noise, a graze the compliant approach and pull tolerate
KEEP_CLEAR_M = 0.01  # grasps whose approach keeps this far from the scene (its points' spacing: a surface's edge lies
# up to that far past its last point) and in front of the fronts' plane go first, then the others, those keeping
# farthest first: a graze pushing a finger makes the tool ease back off the handle before it closes, or holds that
# finger off the handle
PLANE_BAND_M = 0.01  # the fronts' plane and what lies behind it: the fingers stop in front of it (the D415's noise)
SCENE_STEP = 4  # the scene is every 4th pixel in each direction (about 1 cm apart at 1 m)
PITCHES_RAD = (GRASP_PITCH_RAD, 0.0, -GRASP_PITCH_RAD)  # the grasps tried, in order: tilted down (the usual), level,
# then tilted up (the hand, 21 cm along the fingers' closing direction, leans its upper edge out from an overhang)
POCKET_DEPTH_M = 0.0  # a recessed pull the usual depth keeps from clearing the scene is held with the pads' middle
# on the lip its pocket's mouth shows, the hand farther out of the front (under a counter's overhang)
GRIP_MARGIN_M = 0.015  # fingers opened only as wide as a handle needs clear it by this much each side: the pointed
# handle's error (about 1 cm) and the calibration's 5 mm

Pulls = Callable[[np.ndarray], list[list[np.ndarray]]]  # a grasp pose -> the pulls planned from it, most wanted first


@dataclass(frozen=True)
class Scene:
    """What a gripper at the pointed front can touch: `points` standing out of the fronts' plane (`origin`, outward
    unit `normal`), which the plane itself stands for."""

    points: cKDTree
    origin: np.ndarray
    normal: np.ndarray


def scene_tree(frame: Frame, pointed: PointedPart) -> Scene:
    """The scene a gripper at the pointed front can touch, from `frame` (the first, the arm's depth removed)."""
    step = SCENE_STEP
    K = np.diag([1.0 / step, 1.0 / step, 1.0]) @ frame.intrinsics.K
    points = depth_to_points(frame.depth_m[::step, ::step], K, T_base_camera=frame.T_base_camera)
    front = pointed.front
    plane = front.plane
    half = (front.width_m / 2 + EDGE_BAND_M, front.height_m / 2 + EDGE_BAND_M)  # with an edge pull's tab
    points = standing_out(points, plane.origin, plane.right, plane.up, plane.normal, half, PLANE_BAND_M, MAX_STANDOFF_M)
    handle = pointed.handle  # its own box too: a handle on the front's edge may stand past the front's rectangle
    handle_half = (handle.length_m / 2 + EDGE_BAND_M, handle.thickness_m / 2 + PLANE_BAND_M, MAX_STANDOFF_M)
    points = outside_box(points, handle.centre, np.array([handle.bar, handle.close, handle.normal]), handle_half)
    return Scene(cKDTree(points), plane.origin, plane.normal)


def clear_grasps(handle: Handle, scene: Scene, pulls: Pulls, approach_m: float, max_opening_m: float
                 ) -> list[tuple[np.ndarray, float]]:
    """The grasps (pose and finger opening) of `ranked_grasps`, in its order."""
    return [(T, opening) for T, opening, _ in ranked_grasps(handle, scene, pulls, approach_m, max_opening_m)]


def ranked_grasps(handle: Handle, scene: Scene, pulls: Pulls, approach_m: float, max_opening_m: float
                  ) -> list[tuple[np.ndarray, float, bool]]:
    """The grasps (pose, finger opening and whether it grazes the scene) whose approach (from `approach_m` out, the
    fingers open) and first planned pull (the fingers closed on the handle) keep clear of `scene` (CLEARANCE_M), the
    approach in front of the fronts' plane too (PLANE_BAND_M deep at most; a tilted finger's far corner dips toward it;
    a recessed pull's pocket lies behind it), in the order wanted: where the first planned pull is straight (a
    drawer's), those whose approach keeps KEEP_CLEAR_M from the scene and in front of the fronts' plane (but into a
    pocket) first, then the others, the nearer to the scene or the deeper behind the plane the later, those grazing the
    scene (reaching into it, within CLEARANCE_M) after all that do not: a fingertip meeting the front behind the handle
    only stops the compliant approach short, which easing off the press undoes, but a hand resting on a counter's
    overhang or a neighbour beside the handle holds it where centring the handle between the fingers must move it; along
    an arc (a door's) as tried, which is what the arc asks (the tilt down keeps the wrist off its limit, a knob's
    fingers close level as the door turns); ties as tried: a knob held as found then turned a quarter, each going in as
    deep as the handle asks, then for a recessed pull to POCKET_DEPTH_M, each tilted down, level, then up (PITCHES_RAD;
    level first into a recessed pull), each with the fingers opened as the handle asks, then only as wide as it needs
    (its thickness and GRIP_MARGIN_M each side); the grasps from above (FROM_ABOVE_RAD) after all of those. EpisodeStop
    saying where the gripper would touch the scene when none does."""
    openings = [handle.open_m or max_opening_m]
    closed = 0.0 if handle.thickness_m is None else handle.thickness_m
    if handle.thickness_m is not None and closed + 2 * GRIP_MARGIN_M < openings[0]:
        openings.append(closed + 2 * GRIP_MARGIN_M)
    turned = replace(handle, bar=np.cross(handle.normal, handle.bar))  # a knob is held either way round
    clear, contact, during = [], None, ""
    pitches = (0.0, *PITCHES_RAD[::2]) if handle.found == "recessed pull" else PITCHES_RAD  # into a pocket, level
    # first: tilted, the fingers' outer faces climb toward its walls as they go in
    pitches = (*pitches, *FROM_ABOVE_RAD)
    depths = [handle.depth_m]
    if handle.found == "recessed pull" and handle.depth_m > POCKET_DEPTH_M:  # not a tab's or a bar's: their fingers
        # pass a counter's lower edge, which the scene's points miss by up to their spacing
        depths.append(POCKET_DEPTH_M)
    for held, depth, pitch in itertools.product([handle, turned] if handle.found == "knob" else [handle],
                                                depths, pitches):
        T = grasp_pose(held, depth, pitch)
        planned = pulls(T)[0]
        pull = first_contact(scene.points, [T, *planned], parallel_gripper(closed, max_opening_m), CLEARANCE_M)
        chords = np.array([P[:3, 3] for P in planned]) - T[:3, 3]
        swings = float(chords[0] @ chords[-1]) < (1 - 1e-6) * np.linalg.norm(chords[0]) * np.linalg.norm(chords[-1])
        # the first planned pull is an arc (a door's)
        path = [pregrasp_pose(T, approach_m), T]
        for opening in openings:
            gripper = parallel_gripper(opening, max_opening_m)
            touch = pull or first_contact(scene.points, path, gripper, CLEARANCE_M)
            if touch is None and handle.found != "recessed pull":
                touch = first_behind(path, gripper, scene.origin, scene.normal, PLANE_BAND_M)
            if touch is None:
                margin, behind = (KEEP_CLEAR_M, 0.0) if swings else _kept(handle, scene, path, gripper)
                kept = -min(margin, -behind) if behind > 0 else -margin
                clear.append((pitch in FROM_ABOVE_RAD, margin < 0, kept, len(clear), T, opening))
            elif contact is None:
                contact, during = touch, "first pull" if pull is not None else "approach"
    if clear:
        return [(T, opening, grazes) for _, grazes, _, _, T, opening in sorted(clear, key=lambda c: c[:4])]
    p = contact.point
    raise EpisodeStop(StopReason.NO_CLEAR_PATH, f"the gripper's {contact.box} would touch the scene at ({p[0]:.2f}, "
                      f"{p[1]:.2f}, {p[2]:.2f}) m during the {during} ({_where(p, handle)}), however it approached: "
                      "clear what stands there, or move the robot so that it reaches the handle from another side")


def _kept(handle: Handle, scene: Scene, path: list[np.ndarray], gripper: tuple[ToolBox, ...]
          ) -> tuple[float, float]:
    """How far the gripper moving through `path` keeps from `scene` (KEEP_CLEAR_M at most; negative: that deep into
    it) and how deep it reaches behind the fronts' plane (but into a pocket)."""
    margin = clearance(scene.points, path, gripper, KEEP_CLEAR_M)
    return margin, 0.0 if handle.found == "recessed pull" else depth_behind(path, gripper, scene.origin, scene.normal)


def _where(point: np.ndarray, handle: Handle) -> str:
    """Where `point` lies from the handle, in words."""
    d = point - handle.center
    up = float(d[2])
    side = float(d @ np.cross(np.array([0.0, 0.0, 1.0]), handle.normal))
    if abs(up) >= abs(side):
        return f"{abs(up) * 100:.0f} cm {'above' if up > 0 else 'below'} the handle"
    return f"{abs(side) * 100:.0f} cm beside the handle"
