"""Handle and grasp geometry from the first frame's cloud (pure functions, base frame, metres, z up)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from deploy.geometry.boxes import front_direction
from deploy.geometry.types import Axis, Box, JointType
from drivers.arm.grasping import GRASP_DEPTH_M, GRASP_PITCH_RAD, LIMIT_MARGIN_RAD, UP, pregrasp_pose
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
REGRASP_RADIUS_M = 0.12  # a slipped handle is looked for this close to where the gripper held it
APPROACH_STEP_M = 0.025  # the planned approach is followed through a pose every this much (a short arm's joints
# turn fast near the handle: the path check needs its waypoints dense enough to tell a turn from a branch change)
HANDLE_MIN_STANDOFF_M, HANDLE_MAX_STANDOFF_M = 0.01, 0.08  # a handle stands this far out of its front


@dataclass(frozen=True)
class Handle:
    """A handle seen on the first frame: grip centre, outward front normal, bar direction (unit)."""

    center: np.ndarray
    normal: np.ndarray
    bar: np.ndarray
    points: int


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


def grasp_pose(handle: Handle, depth_m: float = GRASP_DEPTH_M, pitch_rad: float = GRASP_PITCH_RAD) -> np.ndarray:
    """Tool pose (4x4) grasping the handle from the front (drivers.arm.grasping.grasp_pose)."""
    return bar_grasp_pose(handle.center, handle.normal, handle.bar, depth_m, pitch_rad)


def pull_poses(path: PathFn, length: float, step: float) -> list[np.ndarray]:
    """Tool poses along `path` (s from 0 to `length`, m or rad) every `step` or finer, at least 6, s = 0 left out."""
    n = max(6, int(np.ceil(length / step)))
    return [path(length * k / n) for k in range(1, n + 1)]


def pregrasp_configuration(
    kin: Kinematics, q_start: np.ndarray, T_grasp: np.ndarray, pulls: Sequence[list[np.ndarray]], approach_m: float
) -> np.ndarray:
    """Joints at the pre-grasp pose from which the approach and a pull (tool poses after the grasp) stay farthest
    from singularities (largest smallest singular value of the Jacobian along them) and inside the joint limits;
    the Panda is redundant, so a few elbow seeds facing the handle are tried. `pulls` are the pulls wanted, most
    wanted first (e.g. a door's arc, then shorter ones): the first that some seed carries decides. Raises IKError
    when none does."""
    n = max(1, int(np.ceil(approach_m / APPROACH_STEP_M)))
    approach = [pregrasp_pose(T_grasp, approach_m * (n - k) / n) for k in range(n)]  # from the pre-grasp pose on
    for poses in pulls:
        best = well_conditioned_start(kin, [*approach, T_grasp, *poses], q_start, LIMIT_MARGIN_RAD)
        if best is not None:
            return best
    p = T_grasp[:3, 3]
    raise IKError(
        f"handle at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m is out of reach: no arm configuration reaches "
        "it and pulls it clear of joint limits and singularities; move the cabinet or the robot closer"
    )


def hinge_prior(handle: Handle, object_points: np.ndarray, body_box: Box) -> Axis:
    """A door's likely hinge before any motion: the vertical edge of the front face farthest from the
    handle (handles sit near the free edge), at the handle's height; opening pulls the handle outward.

    The front face is the object points within FACE_BAND_M of the front plane (its depth the median of
    the points near the handle); its edges are the 2nd and 98th lateral percentiles. With too few face
    points the body box's front edges are used instead.
    """
    side = np.cross(UP, handle.normal)
    pts = np.asarray(object_points, float).reshape(-1, 3)
    depth = pts @ handle.normal
    near = np.linalg.norm(pts - handle.center, axis=1) < FRONT_RADIUS_M
    enough = near.sum() >= MIN_FRONT_POINTS
    face = pts[np.abs(depth - np.median(depth[near])) < FACE_BAND_M] if enough else pts[:0]
    if len(face) >= MIN_FRONT_POINTS:
        lateral = np.percentile(face @ side, [2, 98])
        plane = float(np.median(face @ handle.normal))
    else:
        corners = body_box.corners()
        lateral = np.array([(corners @ side).min(), (corners @ side).max()])
        plane = float((corners @ handle.normal).max())
    handle_lateral = handle.center @ side
    edge = lateral[0] if abs(lateral[0] - handle_lateral) > abs(lateral[1] - handle_lateral) else lateral[1]
    origin = handle.center + (edge - handle_lateral) * side + (plane - handle.center @ handle.normal) * handle.normal
    direction = UP if np.cross(UP, handle.center - origin) @ handle.normal >= 0 else -UP
    return Axis(JointType.REVOLUTE, origin, direction.copy(), confidence=0.0)
