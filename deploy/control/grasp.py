"""Handle and grasp geometry from the first frame's cloud (pure functions, base frame, metres, z up)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation
from scipy.stats import theilslopes

from deploy.geometry.boxes import front_direction
from deploy.geometry.types import Axis, Box, JointType
from deploy.perception.handle import Handle as PointedHandle
from drivers.arm.grasping import GRASP_DEPTH_M, GRASP_PITCH_RAD, LIMIT_MARGIN_RAD, UP, approach_poses
from drivers.arm.grasping import grasp_pose as bar_grasp_pose
from drivers.arm.kinematics import Kinematics, well_conditioned_start
from drivers.arm.motion import PathFn
from drivers.errors import IKError

BAR_HALF_THICKNESS_M = 0.008  # the grip centre lies this far behind the bar's front surface
BAR_ELONGATION = 2.0  # principal spread ratio above which the handle is a bar with a direction
MIN_HANDLE_POINTS = 5
FRONT_RADIUS_M = 0.15  # the front face is fitted to object points this close to the handle
MIN_FRONT_POINTS = 30
PLANE_TOLERANCE_M = 0.004  # RANSAC inlier distance of the front plane
FACE_BAND_M = 0.01  # points this close to the front plane belong to the front face
SURE_EDGE_SHARE = 1.0 / 3.0  # a handle this near one edge of its front (share of the width) marks the other as
# the hinge
MIN_SIDE_TURN_RAD = float(np.radians(0.5))  # a front turned less than this tells no hinge side (the depth's noise)
MIN_MOVED_M = 0.01  # a front that moved out more than this moved with the door (the depth's steps at 1-2 m)
SIDE_BIN_M = 0.02  # the door's motion is read across its front in bins this wide
REGRASP_RADIUS_M = 0.12  # a slipped handle is looked for this close to where the gripper held it
HALF_TURN = np.diag([-1.0, -1.0, 1.0, 1.0])  # a tool pose turned half a turn about its approach (its z)
APPROACH_STEP_M = 0.025  # the planned approach is followed through a pose every this much (a short arm's joints
# turn fast near the handle: the path check needs its waypoints dense enough to tell a turn from a branch change)
HANDLE_MIN_STANDOFF_M, HANDLE_MAX_STANDOFF_M = 0.01, 0.08  # a handle stands this far out of its front
FINGERTIPS_PAST_TOOL_M, FINGER_HALF_WIDTH_M = 0.007, 0.0105  # a Franka hand's fingertips reach 7 mm past its tool
# frame, each finger 2.1 cm wide (deploy/geometry/clearance.py)
FACE_MARGIN_M = 0.005  # the fingertips stop this short of the front behind a handle: the calibration's error
MIN_GRASP_DEPTH_M = -0.005  # the tool frame goes at most this far short of a handle's grip centre (the pads still close
# on it: they are 2 cm long)


@dataclass(frozen=True)
class Handle:
    """A handle seen on the first frame: grip centre, outward front normal, bar direction (unit); `found` says how
    (for the log); `open_m` how wide the gripper opens to approach it (None: fully), `thickness_m` what the fingers
    close on (None: not known), `depth_m` how far past the grip centre the tool frame goes."""

    center: np.ndarray
    normal: np.ndarray
    bar: np.ndarray
    points: int
    found: str = "protruding points"
    open_m: float | None = None
    thickness_m: float | None = None
    depth_m: float = GRASP_DEPTH_M


def pointed_handle(handle: PointedHandle, vertical_default: bool) -> Handle:
    """The grasp's handle of a pointed front's (deploy/perception/handle.py): its grip centre, the front's normal
    made horizontal (fronts are vertical; the grasp tilts its own approach) and the bar across the fingers' closing
    direction, in the front's plane. A round knob (shorter than BAR_ELONGATION times its thickness: a round knob seen
    at a slant reads longer, a cup half hidden by a neighbour twice as long or more), held the same way round, gets a
    vertical bar when `vertical_default` (a door's: the fingers then close level, as the door turns) and else a
    horizontal one."""
    normal = np.array([handle.normal[0], handle.normal[1], 0.0])
    normal /= np.linalg.norm(normal)
    if handle.kind == "knob" and handle.length_m < BAR_ELONGATION * handle.thickness_m:
        bar = UP.copy() if vertical_default else np.cross(normal, UP)
    else:
        bar = np.cross(normal, handle.close)
    thickness = None if handle.kind == "recessed pull" else handle.thickness_m  # a pocket's width is not its bar's
    depth = grip_depth_m(handle.clearance_m, handle.kind == "knob")
    return Handle(np.asarray(handle.centre, float), normal, bar / np.linalg.norm(bar), 0, handle.kind, handle.open_m,
                  thickness, depth)


def grip_depth_m(clearance_m: float, knob: bool, pitch_rad: float = GRASP_PITCH_RAD) -> float:
    """How far past a handle's grip centre the tool frame goes along an approach tilted down by `pitch_rad`, with
    `clearance_m` of room behind the centre (along the front's normal): as deep as GRASP_DEPTH_M, but with the
    fingers' leading corner (the tips' upper edge: the tilt swings it toward the front) short of the front (a short
    tab, a knob near its front), by FACE_MARGIN_M more around a knob (the fingers pass beside its head onto the
    door, where a lip's pads hold its edge); at most MIN_GRASP_DEPTH_M short of the centre."""
    reach = FINGERTIPS_PAST_TOOL_M * np.cos(pitch_rad) + FINGER_HALF_WIDTH_M * np.sin(pitch_rad)
    depth = (clearance_m - (FACE_MARGIN_M if knob else 0.0) - reach) / np.cos(pitch_rad)
    return float(np.clip(depth, MIN_GRASP_DEPTH_M, GRASP_DEPTH_M))


def _local_plane(points: np.ndarray, near: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The points within `radius_m` of `near` and their dominant plane (RANSAC) as (a, b, c, d) with
    a x + b y + c z + d = 0 and a unit normal; None with fewer than MIN_FRONT_POINTS points."""
    pts = np.asarray(points, float).reshape(-1, 3)
    local = pts[np.linalg.norm(pts - near, axis=1) < radius_m]
    if len(local) < MIN_FRONT_POINTS:
        return None
    o3d.utility.random.seed(0)
    plane, _ = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(local)).segment_plane(PLANE_TOLERANCE_M, 3, 200)
    return local, np.asarray(plane, float)


def front_normal(
    object_points: np.ndarray, near: np.ndarray, body_box: Box, viewpoint: np.ndarray
) -> np.ndarray:
    """Unit horizontal normal of the front face around `near` (the handle), facing `viewpoint`: the
    dominant plane (RANSAC) of the object points within FRONT_RADIUS_M; the body box's front face when
    that plane is missing or not vertical."""
    fit = _local_plane(object_points, near, FRONT_RADIUS_M)
    normal = np.zeros(3) if fit is None else np.array([fit[1][0], fit[1][1], 0.0])
    if np.linalg.norm(normal) < np.cos(np.radians(30)):  # missing, or a top / side face
        normal = front_direction(body_box, viewpoint)
    normal /= np.linalg.norm(normal)
    return normal if (np.asarray(viewpoint, float) - near) @ normal >= 0 else -normal


def find_handle(
    handle_points: np.ndarray, object_points: np.ndarray, body_box: Box, viewpoint: np.ndarray,
    vertical_default: bool,
) -> Handle | None:
    """The handle from its points: centre behind the bar's front surface (normal from `front_normal`), bar
    along the principal axis (or vertical / horizontal by `vertical_default` for knobs). None with fewer
    than MIN_HANDLE_POINTS."""
    pts = np.asarray(handle_points, float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) < MIN_HANDLE_POINTS:
        return None
    normal = front_normal(object_points, pts.mean(axis=0), body_box, viewpoint)
    depth = pts @ normal
    center = np.median(pts, axis=0)
    center += (np.percentile(depth, 90) - BAR_HALF_THICKNESS_M - center @ normal) * normal
    across = pts - pts.mean(axis=0)
    across -= np.outer(across @ normal, normal)  # spread in the front plane
    _, s, vt = np.linalg.svd(across, full_matrices=False)
    if len(s) > 1 and s[0] > BAR_ELONGATION * max(s[1], 1e-9):
        bar = vt[0]
    else:
        bar = UP - normal * (normal @ UP) if vertical_default else np.cross(normal, UP)
    return Handle(center, normal, bar / np.linalg.norm(bar), len(pts))


def protruding_points(
    object_points: np.ndarray, near: np.ndarray, viewpoint: np.ndarray, radius_m: float = REGRASP_RADIUS_M
) -> np.ndarray:
    """Object points within `radius_m` of `near` that stand 1-8 cm out of the local front plane toward the
    viewpoint: the handle of a front that has moved out of the first frame's body box (re-grasp)."""
    fit = _local_plane(object_points, near, radius_m)
    if fit is None:
        return np.empty((0, 3))
    local, plane = fit
    normal, offset = plane[:3], float(plane[3])
    if (np.asarray(viewpoint, float) @ normal + offset) < 0:
        normal, offset = -normal, -offset
    height = local @ normal + offset
    return local[(height > HANDLE_MIN_STANDOFF_M) & (height < HANDLE_MAX_STANDOFF_M)]


def back_along_path(axis: Axis | None, point: np.ndarray, travel: float, spacing_m: float) -> list[np.ndarray]:
    """`point`, then `point` carried back along the joint's path (about or along `axis`) every `spacing_m` of
    its travel, up to `travel` (m or rad): where a part released after opening by `travel` may have gone back
    to (a door swinging shut, a drawer sliding in). Only `point` without an axis."""
    point = np.asarray(point, float)
    if axis is None or travel <= 0:
        return [point]
    d = axis.direction / np.linalg.norm(axis.direction)
    if axis.joint_type is JointType.PRISMATIC:
        n = int(np.ceil(travel / spacing_m))
        return [point - d * travel * k / n for k in range(n + 1)] if n else [point]
    r = point - axis.origin
    radius = float(np.linalg.norm(r - (r @ d) * d))
    n = int(np.ceil(travel * radius / spacing_m))
    turns = [-travel * k / n for k in range(n + 1)] if n else [0.0]
    return [axis.origin + Rotation.from_rotvec(d * t).apply(r) for t in turns]


def grasp_pose(handle: Handle, depth_m: float | None = None, pitch_rad: float = GRASP_PITCH_RAD) -> np.ndarray:
    """Tool pose (4x4) grasping the handle from the front (drivers.arm.grasping.grasp_pose), the tool frame `depth_m`
    past its grip centre (None: the handle's)."""
    return bar_grasp_pose(handle.center, handle.normal, handle.bar, handle.depth_m if depth_m is None else depth_m,
                          pitch_rad)


def pull_poses(path: PathFn, length: float, step: float) -> list[np.ndarray]:
    """Tool poses along `path` (s from 0 to `length`, m or rad) every `step` or finer, at least 6, s = 0 left out."""
    n = max(6, int(np.ceil(length / step)))
    return [path(length * k / n) for k in range(1, n + 1)]


def pregrasp_configuration(
    kin: Kinematics, q_start: np.ndarray, T_grasp: np.ndarray, pulls: Sequence[list[np.ndarray]], approach_m: float,
    swung: bool = False,
) -> np.ndarray:
    """Joints at the pre-grasp pose from which the approach and a pull (tool poses after the grasp) stay farthest
    from singularities (largest smallest singular value of the Jacobian along them) and inside the joint limits;
    the Panda is redundant, so a few elbow seeds facing the handle are tried. `pulls` are the pulls wanted, most
    wanted first (e.g. a door's arc, then shorter ones): the first that some seed carries decides. `swung`: the
    seeds have the elbow swung out sideways instead (`well_conditioned_start`), a posture to try only when the usual
    ones carry no grasp. Raises IKError when none carries any."""
    carried = _carried_pull(kin, q_start, T_grasp, pulls, approach_m, swung)
    if carried is None:
        raise _out_of_reach(T_grasp)
    return carried[1]


def pregrasp_either_way(
    kin: Kinematics, q_start: np.ndarray, T_grasp: np.ndarray,
    pulls: Callable[[np.ndarray], Sequence[list[np.ndarray]]], approach_m: float, swung: bool = False,
    whole: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The grasp and its pre-grasp joints (`pregrasp_configuration`, `pulls` of the grasp pose): `T_grasp`, or, where
    that carries a pull but not the most wanted one, it turned half a turn about its approach when that one carries
    a more wanted pull (a parallel gripper holds a handle either way round: the wrist's last joint, near its limit
    as found, takes the door's turn the other way round). IKError when `T_grasp` carries no pull (the next grasp
    is tried as found), or with `whole` when neither way round carries the most wanted one."""
    found = _carried_pull(kin, q_start, T_grasp, pulls(T_grasp), approach_m, swung)
    if found is None:
        raise _out_of_reach(T_grasp)
    if found[0] > 0:
        T_turned = T_grasp @ HALF_TURN
        turned = _carried_pull(kin, q_start, T_turned, pulls(T_turned), approach_m, swung)
        if turned is not None and turned[0] < found[0]:
            T_grasp, found = T_turned, turned
    if whole and found[0] > 0:
        raise _out_of_reach(T_grasp)
    return T_grasp, found[1]


def _carried_pull(kin: Kinematics, q_start: np.ndarray, T_grasp: np.ndarray, pulls: Sequence[list[np.ndarray]],
                  approach_m: float, swung: bool) -> tuple[int, np.ndarray] | None:
    """(index of the first of `pulls` some seed carries, its pre-grasp joints); None when none is carried."""
    approach = approach_poses(T_grasp, approach_m, max(1, int(np.ceil(approach_m / APPROACH_STEP_M))))
    for index, poses in enumerate(pulls):
        best = well_conditioned_start(kin, [*approach, T_grasp, *poses], q_start, LIMIT_MARGIN_RAD, swung)
        if best is not None:
            return index, best
    return None


def _out_of_reach(T_grasp: np.ndarray) -> IKError:
    p = T_grasp[:3, 3]
    return IKError(
        f"handle at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m is out of reach: no arm configuration reaches "
        "it and pulls it clear of joint limits and singularities; move the cabinet or the robot closer"
    )


def _front_edges(handle: Handle, object_points: np.ndarray, body_box: Box, front_corners: np.ndarray | None
                 ) -> tuple[np.ndarray, float]:
    """The front face's vertical edges (lateral coordinates along UP x normal, ascending) and its plane's depth along
    the handle's normal: the pointed front's rectangle when given (`front_corners`, (4, 3) base frame); else the
    object points within FACE_BAND_M of the front plane (its depth the median of the points near the handle), its
    edges the 2nd and 98th lateral percentiles; with too few face points the body box's front edges."""
    side = np.cross(UP, handle.normal)
    pts = np.asarray(object_points, float).reshape(-1, 3)
    depth = pts @ handle.normal
    near = np.linalg.norm(pts - handle.center, axis=1) < FRONT_RADIUS_M
    enough = near.sum() >= MIN_FRONT_POINTS and front_corners is None
    face = pts[np.abs(depth - np.median(depth[near])) < FACE_BAND_M] if enough else pts[:0]
    if front_corners is not None:
        corners = np.asarray(front_corners, float)
        return np.array([(corners @ side).min(), (corners @ side).max()]), float(np.mean(corners @ handle.normal))
    if len(face) >= MIN_FRONT_POINTS:
        return np.percentile(face @ side, [2, 98]), float(np.median(face @ handle.normal))
    corners = body_box.corners()
    return np.array([(corners @ side).min(), (corners @ side).max()]), float((corners @ handle.normal).max())


def hinge_prior(handle: Handle, object_points: np.ndarray, body_box: Box, front_corners: np.ndarray | None = None,
                side: float = 0.0) -> Axis:
    """A door's likely hinge before any motion: a vertical edge of the front face (`_front_edges`) at the handle's
    height, opening pulling the handle outward. The edge lies on the `side` of the handle (its sign along
    UP x normal, as `hinge_side` tells it) when one is given; else it is the edge farthest from the handle (handles
    sit near the free edge)."""
    lateral, plane = _front_edges(handle, object_points, body_box, front_corners)
    handle_lateral = handle.center @ np.cross(UP, handle.normal)
    if side:
        edge = lateral[0] if side < 0 else lateral[1]
    else:
        edge = lateral[0] if abs(lateral[0] - handle_lateral) > abs(lateral[1] - handle_lateral) else lateral[1]
    origin = handle.center + (edge - handle_lateral) * np.cross(UP, handle.normal) \
        + (plane - handle.center @ handle.normal) * handle.normal
    direction = UP if np.cross(UP, handle.center - origin) @ handle.normal >= 0 else -UP
    return Axis(JointType.REVOLUTE, origin, direction.copy(), confidence=0.0)


def hinge_side_sure(handle: Handle, object_points: np.ndarray, body_box: Box, front_corners: np.ndarray | None = None
                    ) -> bool:
    """Whether the front face tells the hinge's side: the handle lies within SURE_EDGE_SHARE of the front's width
    from one of its edges (the hinge is then the other). A handle farther in (a front found too wide: a pair of
    doors taken for one, a front cut by the image's edge; a knob in the middle of a door) leaves it open."""
    lateral, _ = _front_edges(handle, object_points, body_box, front_corners)
    width = float(lateral[1] - lateral[0])
    nearer = float(np.min(np.abs(lateral - handle.center @ np.cross(UP, handle.normal))))
    return width > 0 and nearer < SURE_EDGE_SHARE * width


def hinge_side(before: np.ndarray, after: np.ndarray, handle: Handle, pulled_m: float) -> float:
    """The hinge's side of the handle (+1 or -1 along UP x normal; 0 when the motion does not tell) from the same
    pixels' points (base frame, (N, 3) each) before and after a straight pull of `pulled_m`: a door's points move
    out the less the nearer its hinge, so their outward motion falls toward it. The points within FRONT_RADIUS_M of
    the handle's height are binned across the front every SIDE_BIN_M, each bin's motion its median (the depth's
    noise); bins that moved out between MIN_MOVED_M and twice the pull are the door's (a neighbour and the body
    stay); the trend is their Theil-Sen slope, below tan(MIN_SIDE_TURN_RAD) it tells nothing."""
    before, after = np.asarray(before, float).reshape(-1, 3), np.asarray(after, float).reshape(-1, 3)
    level = np.abs(before[:, 2] - handle.center[2]) < FRONT_RADIUS_M
    out = (after[level] - before[level]) @ handle.normal
    bins = np.round((before[level] - handle.center) @ np.cross(UP, handle.normal) / SIDE_BIN_M).astype(int)
    lateral, moved = [], []
    for b in np.unique(bins):
        in_bin = out[bins == b]
        if len(in_bin) >= MIN_HANDLE_POINTS and MIN_MOVED_M < np.median(in_bin) < 2.0 * pulled_m:
            lateral.append(b * SIDE_BIN_M)
            moved.append(float(np.median(in_bin)))
    if len(moved) < 3:
        return 0.0
    slope = theilslopes(moved, lateral)[0]
    return 0.0 if abs(slope) < np.tan(MIN_SIDE_TURN_RAD) else float(-np.sign(slope))
