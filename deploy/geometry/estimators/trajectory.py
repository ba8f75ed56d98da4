"""The joint axis from the path of the gripper (handle) while it pulls: a line or a circular arc.

Fits are robust: least-median-of-squares sampling over minimal sets (fixed seed), then least squares
on the inliers. `fit_trajectory` picks the joint type when none is given (see its docstring).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis

NOISE_FLOOR_M = 5e-4
"""sigma0 of the BIC: residuals below it count as noise, so noise-free data does not favour a model."""
OUTLIER_CAP_M = 0.01
"""Residuals are truncated here when the two models are compared, so gross outliers weigh the same."""
MAX_RADIUS_M = 3.0
"""A circle wider than this is a line for classification (a door's radius is well under 1.5 m)."""
MIN_SPREAD_M = 0.005
MIN_ROTATION_DEG = 3.0
"""With orientations, a gripper rotation at least this large marks the joint as revolute."""
_MIN_INLIER_M = 1e-4
_SAMPLES = 300
_SEED = 0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _inlier_threshold(residuals: np.ndarray, n_params: int) -> float:
    """Rousseeuw's LMedS scale, times 2.5, with a floor for noise-free data."""
    n = len(residuals)
    scale = 1.4826 * (1 + 5 / max(n - n_params, 1)) * float(np.sqrt(np.median(residuals**2)))
    return max(2.5 * scale, _MIN_INLIER_M)


def _sample_sets(n: int, size: int) -> np.ndarray:
    """Up to `_SAMPLES` distinct random index sets of `size` distinct points (fixed seed)."""
    rng = np.random.default_rng(_SEED)
    sets = np.argsort(rng.random((_SAMPLES, n)), axis=1)[:, :size]
    return np.unique(np.sort(sets, axis=1), axis=0)


def _line_residuals(points: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    d = points - origin
    return np.linalg.norm(d - np.outer(d @ direction, direction), axis=1)


def _check_points(points: np.ndarray, minimum: int, what: str) -> np.ndarray:
    points = np.asarray(points, float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{what}: points must have shape (N, 3), got {points.shape}")
    if len(points) < minimum:
        raise ValueError(f"{what}: needs at least {minimum} points, got {len(points)}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{what}: points contain NaN or inf; drop those samples first")
    return points


def fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Robust 3D line: (origin, unit direction, RMS of the inliers' distances, m).

    Raises ValueError for fewer than 2 points or when all points coincide.
    """
    line, _ = _fit_line(_check_points(points, 2, "fit_line"))
    return line


def _fit_line(points: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray, float], np.ndarray]:
    """The line and its inlier mask."""
    pairs = _sample_sets(len(points), 2)
    starts, chords = points[pairs[:, 0]], points[pairs[:, 1]] - points[pairs[:, 0]]
    lengths = np.linalg.norm(chords, axis=1)
    keep = lengths > 1e-9
    if not keep.any():
        raise ValueError("fit_line: all points coincide, so they define no line")
    starts, directions = starts[keep], chords[keep] / lengths[keep, None]
    d = points[None] - starts[:, None]
    along = np.einsum("mnk,mk->mn", d, directions)
    medians = np.median(np.linalg.norm(d - along[..., None] * directions[:, None], axis=2), axis=1)
    best = starts[np.argmin(medians)], directions[np.argmin(medians)]
    inliers = np.ones(len(points), bool)
    for _ in range(2):
        residuals = _line_residuals(points, *best)
        inliers = residuals <= _inlier_threshold(residuals, 4)
        origin = points[inliers].mean(axis=0)
        direction = np.linalg.svd(points[inliers] - origin)[2][0]
        best = (origin, direction)
    residuals = _line_residuals(points, *best)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    return (best[0], best[1], rms), inliers


def _circle_residuals(
    points: np.ndarray, center: np.ndarray, normal: np.ndarray, radius: float
) -> np.ndarray:
    """Euclidean distance of each point to the circle."""
    d = points - center
    height = d @ normal
    in_plane = np.sqrt(np.maximum(np.einsum("ij,ij->i", d, d) - height**2, 0.0))
    return np.hypot(in_plane - radius, height)


def _circumcircles(p1: np.ndarray, p2: np.ndarray, p3: np.ndarray):
    """(centers, unit normals, radii) of the circles through (M,3) point triples, collinear ones dropped."""
    a, b = p2 - p1, p3 - p1
    n = np.cross(a, b)
    nn = np.einsum("ij,ij->i", n, n)
    aa, bb = np.einsum("ij,ij->i", a, a), np.einsum("ij,ij->i", b, b)
    keep = nn > 1e-12 * aa * bb
    a, b, n, nn, aa, bb, p1 = a[keep], b[keep], n[keep], nn[keep], aa[keep], bb[keep], p1[keep]
    centers = p1 + np.cross(aa[:, None] * b - bb[:, None] * a, n) / (2 * nn[:, None])
    return centers, n / np.sqrt(nn)[:, None], np.linalg.norm(centers - p1, axis=1)


def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u = _unit(np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0]))
    return u, np.cross(normal, u)


def _kasa_circle(points: np.ndarray):
    """Initial circle: plane by SVD, then Kasa's algebraic fit in that plane."""
    mean = points.mean(axis=0)
    normal = np.linalg.svd(points - mean)[2][2]
    u, v = _plane_basis(normal)
    x, y = (points - mean) @ u, (points - mean) @ v
    (a, b, c), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x**2 + y**2, rcond=None)
    r2 = c + (a / 2) ** 2 + (b / 2) ** 2
    if r2 <= 0:
        return None
    return mean + a / 2 * u + b / 2 * v, normal, float(np.sqrt(r2))


def _refine_circle(points: np.ndarray, center: np.ndarray, normal: np.ndarray, radius: float):
    """Geometric least squares (analytic Jacobian) over centre, normal (two tilts) and radius."""
    u, v = _plane_basis(normal)

    def unpack(x):
        return x[:3], normal + x[3] * u + x[4] * v, x[5]

    def parts(x):
        c, m, r = unpack(x)
        n = m / np.linalg.norm(m)
        d = points - c
        height = d @ n
        in_plane = np.sqrt(np.maximum(np.einsum("ij,ij->i", d, d) - height**2, 1e-18))
        return n, d, height, in_plane, r, np.linalg.norm(m)

    def residuals(x):
        _, _, height, in_plane, r, _ = parts(x)
        return np.concatenate([in_plane - r, height])

    def jacobian(x):
        n, d, height, in_plane, _, length = parts(x)
        tilt = (np.column_stack([u, v]) - np.outer(n, n @ np.column_stack([u, v]))) / length
        d_height = np.hstack([np.tile(-n, (len(d), 1)), d @ tilt, np.zeros((len(d), 1))])
        d_in_plane = np.hstack([
            (-d + height[:, None] * n) / in_plane[:, None],
            -height[:, None] * (d @ tilt) / in_plane[:, None],
            -np.ones((len(d), 1)),
        ])
        return np.vstack([d_in_plane, d_height])

    x0 = np.concatenate([center, [0.0, 0.0, radius]])
    solution = least_squares(residuals, x0, jac=jacobian, method="lm")
    c, m, r = unpack(solution.x)
    return c, _unit(m), float(abs(r))


def fit_circle_3d(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Robust 3D circle: (center, unit normal, radius, RMS of the inliers' distances, m).

    Raises ValueError for fewer than 3 points or when the points are collinear (no circle).
    """
    circle, _ = _fit_circle(_check_points(points, 3, "fit_circle_3d"))
    return circle


def _fit_circle(points: np.ndarray):
    """The circle and its inlier mask."""
    triples = _sample_sets(len(points), 3)
    centers, normals, radii = _circumcircles(*(points[triples[:, i]] for i in range(3)))
    if len(centers) == 0:
        raise ValueError("fit_circle_3d: the points are collinear, so they define no circle")
    d = points[None] - centers[:, None]
    height = np.einsum("mnk,mk->mn", d, normals)
    in_plane = np.sqrt(np.maximum(np.einsum("mnk,mnk->mn", d, d) - height**2, 0.0))
    m = int(np.argmin(np.median(np.hypot(in_plane - radii[:, None], height), axis=1)))
    best = centers[m], normals[m], float(radii[m])
    residuals = _circle_residuals(points, *best)
    inliers = residuals <= _inlier_threshold(residuals, 6)
    if inliers.sum() < 3:
        inliers[:] = True
    candidates = [best] + [c for c in [_kasa_circle(points[inliers])] if c is not None]
    refined = [_refine_circle(points[inliers], *c) for c in candidates]
    cost = [np.sum(_circle_residuals(points[inliers], *c) ** 2) for c in refined]
    center, normal, radius = refined[int(np.argmin(cost))]
    residuals = _circle_residuals(points, center, normal, radius)
    inliers = residuals <= _inlier_threshold(residuals, 6)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    return (center, normal, float(radius), rms), inliers


def _bic(residuals: np.ndarray, n_params: int) -> float:
    n = len(residuals)
    rss = float(np.sum(np.minimum(residuals, OUTLIER_CAP_M) ** 2))
    return n * np.log(rss / n + NOISE_FLOOR_M**2) + n_params * np.log(n)


def _trend(values: np.ndarray, mask: np.ndarray) -> float:
    """Sign-bearing trend of `values` with the sample order, over the masked samples."""
    order = np.arange(len(values), dtype=float)[mask]
    return float(np.sum((order - order.mean()) * values[mask]))


def _gripper_turn(quaternions: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Rotation axis w of the orientations relative to the first, and each sample's angle about it (rad).

    w from least squares over R_k w = w, signed so the total rotation is positive; None when the
    gripper turned by less than MIN_ROTATION_DEG (the axis would be noise).
    """
    rotations = Rotation.from_quat(quaternions)
    relative = rotations * rotations[0].inv()
    m = relative.as_matrix() - np.eye(3)
    w = np.linalg.eigh(np.einsum("kji,kjl->il", m, m))[1][:, 0]
    rotvecs = relative.as_rotvec()
    if np.degrees(np.max(np.linalg.norm(rotvecs, axis=1))) < MIN_ROTATION_DEG:
        return None
    w = w if rotvecs.sum(axis=0) @ w >= 0 else -w
    return w, rotvecs @ w


def _confidence(inlier_fraction: float, motion: float, rms_m: float) -> float:
    """inlier fraction x motion (1 at full scale) x residual factor (0.5 at 2 mm RMS)."""
    return float(np.clip(inlier_fraction * min(motion, 1.0) / (1 + (rms_m / 0.002) ** 2), 0.0, 1.0))


def fit_trajectory(
    positions: np.ndarray, quaternions: np.ndarray | None = None, joint: JointType | None = None
) -> AxisResult:
    """The joint axis from gripper positions (N,3) and optional orientations (N,4, xyzw), oldest first.

    Prismatic: a robust line; direction along the motion (first -> last). Revolute: with orientations,
    the direction comes from the gripper's rotation (least squares over R_k w = w, reliable for short
    arcs) and the centre from a circle fit in the plane normal to it; without, from a 3D circle fit.
    Opening is a positive rotation about the direction; origin = circle centre (the axis point level
    with the handle); radius_m = circle radius.

    Joint type when `joint` is None: revolute when the gripper rotated by >= MIN_ROTATION_DEG, or when
    BIC = n ln(RSS/n + sigma0^2) + k ln n (residuals capped at OUTLIER_CAP_M, sigma0 = NOISE_FLOOR_M,
    k = 4 for a line, 6 for a circle) favours the circle; but a circle wider than MAX_RADIUS_M is a line.
    NoAxis for fewer than 3 samples, non-finite values, less than MIN_SPREAD_M of motion, or no fit.
    """
    positions = np.asarray(positions, float)
    if positions.ndim != 2 or positions.shape[1] != 3 or len(positions) < 3:
        return NoAxis(f"need at least 3 gripper positions (N, 3), got shape {positions.shape}")
    if quaternions is not None:
        quaternions = np.asarray(quaternions, float)
        if quaternions.shape != (len(positions), 4):
            return NoAxis(f"orientations must have shape ({len(positions)}, 4), got {quaternions.shape}")
        if not np.all(np.isfinite(quaternions)) or np.any(np.linalg.norm(quaternions, axis=1) < 1e-9):
            return NoAxis("orientations contain NaN, inf or zero quaternions")
    if not np.all(np.isfinite(positions)):
        return NoAxis("gripper positions contain NaN or inf")
    centred = positions - positions.mean(axis=0)
    spread = float(np.ptp(centred @ np.linalg.svd(centred)[2][0]))
    if spread < MIN_SPREAD_M:
        return NoAxis(
            f"not enough motion yet: {spread * 1000:.1f} mm of {MIN_SPREAD_M * 1000:.0f} mm",
            {"spread_m": spread},
        )
    turn = _gripper_turn(quaternions) if quaternions is not None else None

    (origin, direction, line_rms), line_inliers = _fit_line(positions)
    if joint is not JointType.PRISMATIC:
        try:
            circle, circle_inliers = _revolute_fit(positions, turn)
        except ValueError as error:
            if joint is JointType.REVOLUTE:
                return NoAxis(f"no hinge circle fits the gripper path: {error}")
            circle = None
        if joint is None and circle is not None:
            line_bic = _bic(_line_residuals(positions, origin, direction), 4)
            circle_bic = _bic(_circle_residuals(positions, *circle[:3]), 6)
            revolute = (turn is not None or circle_bic < line_bic) and circle[2] <= MAX_RADIUS_M
            joint = JointType.REVOLUTE if revolute else JointType.PRISMATIC
        elif joint is None:
            joint = JointType.PRISMATIC
        if joint is JointType.REVOLUTE:
            if circle[2] > MAX_RADIUS_M:
                return NoAxis(
                    f"the gripper path is too straight to locate a hinge: circle radius {circle[2]:.1f} m",
                    {"radius_m": circle[2]},
                )
            return _revolute_axis(positions, circle, circle_inliers, turn)

    start = origin + ((positions[0] - origin) @ direction) * direction
    along = (positions - start) @ direction
    if _trend(along, line_inliers) < 0:
        direction = -direction
    motion = float(np.ptp(along[line_inliers])) / 0.05
    return Axis(
        JointType.PRISMATIC, start, direction,
        confidence=_confidence(line_inliers.mean(), motion, line_rms), residual_m=line_rms,
    )


def _revolute_fit(positions: np.ndarray, turn: tuple[np.ndarray, np.ndarray] | None):
    """(center, normal, radius, rms) and inliers; normal and centre from the gripper turn when there is one.

    With a turn, the positions in the plane normal to w must follow x_k = c + Rot(theta_k) v (rigid
    grasp): linear least squares in (c, v), kept when its RMS is within 2x + 1 mm of the plain circle
    fit's (a grasp that slipped breaks the model, and then the circle fit alone gives the centre).
    """
    if turn is None:
        return _fit_circle(positions)
    w, angles = turn
    heights = positions @ w
    flat = positions - np.outer(heights - np.median(heights), w)
    (center, _, radius, _), inliers = _fit_circle(flat)
    u, v = _plane_basis(w)
    x = np.column_stack([(flat - center) @ u, (flat - center) @ v])[inliers]
    cos, sin = np.cos(angles[inliers]), np.sin(angles[inliers])
    ones, zeros = np.ones_like(cos), np.zeros_like(cos)
    design = np.vstack([
        np.column_stack([ones, zeros, cos, -sin]),
        np.column_stack([zeros, ones, sin, cos]),
    ])
    solution, *_ = np.linalg.lstsq(design, np.concatenate([x[:, 0], x[:, 1]]), rcond=None)
    circle_rms = float(np.sqrt(np.mean(_circle_residuals(flat, center, w, radius)[inliers] ** 2)))
    rigid_rms = float(np.sqrt(np.mean((design @ solution - np.concatenate([x[:, 0], x[:, 1]])) ** 2) * 2))
    if rigid_rms <= 2 * circle_rms + 1e-3:
        center = center + solution[0] * u + solution[1] * v
        radius = float(np.hypot(solution[2], solution[3]))
    residuals = _circle_residuals(positions, center, w, radius)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    return (center, w, radius, rms), inliers


def _revolute_axis(positions, circle, inliers, turn) -> Axis:
    center, normal, radius, rms = circle
    u, v = _plane_basis(normal)
    d = positions - center
    angles = np.unwrap(np.arctan2(d @ v, d @ u))
    if turn is None and _trend(angles, inliers) < 0:
        normal = -normal
    swept_deg = float(np.degrees(np.ptp(angles[inliers])))
    return Axis(
        JointType.REVOLUTE, center, normal,
        confidence=_confidence(inliers.mean(), swept_deg / 20.0, rms), residual_m=rms, radius_m=radius,
    )


def parse_trajectory_text(text: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Samples from text, one per line: `x y z` or `x y z qx qy qz qw` (metres, quaternion xyzw).

    Whitespace or commas separate values; `#` starts a comment; blank lines are skipped. Returns
    positions (N,3) and unit quaternions (N,4) or None. Raises ValueError naming the bad line.
    """
    rows: list[list[float]] = []
    columns = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        fields = [f for f in re.split(r"[\s,]+", line) if f]
        if len(fields) not in (3, 7):
            raise ValueError(
                f"trajectory line {number}: expected 3 values (x y z) or 7 (x y z qx qy qz qw), "
                f"got {len(fields)}: {raw.strip()!r}"
            )
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise ValueError(f"trajectory line {number}: not a number in {raw.strip()!r}") from None
        if not np.all(np.isfinite(values)):
            raise ValueError(f"trajectory line {number}: NaN or inf in {raw.strip()!r}")
        if columns is not None and len(values) != columns:
            raise ValueError(
                f"trajectory line {number}: {len(values)} values but earlier lines have {columns}; "
                "use the same format (with or without quaternions) on every line"
            )
        if len(values) == 7 and np.linalg.norm(values[3:]) < 1e-9:
            raise ValueError(f"trajectory line {number}: zero quaternion in {raw.strip()!r}")
        columns = len(values)
        rows.append(values)
    if not rows:
        return np.zeros((0, 3)), None
    data = np.array(rows)
    if columns == 3:
        return data, None
    return data[:, :3], data[:, 3:] / np.linalg.norm(data[:, 3:], axis=1, keepdims=True)


class TrajectoryEstimator(AxisEstimator):
    """The axis from the gripper poses of the window (forward kinematics), via `fit_trajectory`."""

    name = "trajectory"

    def estimate(self, window: Sequence[Observation], joint: JointType | None = None) -> AxisResult:
        poses = [o.gripper_pose for o in window]
        if any(p is None for p in poses):
            missing = sum(p is None for p in poses)
            return NoAxis(f"gripper poses missing in {missing} of {len(poses)} frames (no arm attached?)")
        if len(poses) < 3:
            return NoAxis(f"need at least 3 gripper poses, got {len(poses)}")
        poses_array = np.asarray(poses, float)
        if not np.all(np.isfinite(poses_array)):
            return NoAxis("gripper poses contain NaN or inf")
        quaternions = Rotation.from_matrix(poses_array[:, :3, :3]).as_quat()
        return fit_trajectory(poses_array[:, :3, 3], quaternions, joint)


def open_trajectory(_argument: str, _config: object = None) -> TrajectoryEstimator:
    return TrajectoryEstimator()
