"""The joint axis from the path of the gripper (handle) while it pulls: a line or a circular arc.

The path is first prepared (`trajectory_path.prepare_path`): its own noise level, tracking glitches
dropped, pauses and uneven sampling evened out on a grid, orientations measured from the start all of
them agree on. Fits are robust (`trajectory_fit`) but must explain FIT_COVERAGE of the cells. Joint
type, when none is given, comes from `classify`: a revolute joint must be shown by an arc the line
cannot explain beyond its extra freedom, or by a gripper turn that follows the travel, and otherwise
the answer is prismatic, or undecided (NoAxis with the reason) when the evidence is too thin or
contradicts itself, or when the hinge's direction would be uncertain by more than MAX_HINGE_SIGMA_DEG.
A direction's sigma counts what one path can show of its bias: the block jackknife, the plane's tilt
over the arc's sagitta, the turn's scatter about other axes over the turn.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.estimators.trajectory_fit import (
    circle_residuals,
    fit_circle_3d,
    fit_circle_inliers,
    fit_line,
    fit_line_inliers,
    plane_basis,
    refine_circle,
)
from deploy.geometry.estimators.trajectory_io import parse_trajectory, parse_trajectory_text
from deploy.geometry.estimators.trajectory_path import (
    PreparedPath,
    bend_coverage,
    effective_fraction,
    jackknife_sigma_deg,
    plane_tilt_deg,
    prepare_path,
    turn_play_deg,
)
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis

__all__ = ["TrajectoryEstimator", "classify", "fit_circle_3d", "fit_line", "fit_trajectory", "fit_trajectory_report",
           "parse_trajectory", "parse_trajectory_text"]

NOISE_FLOOR_M = 5e-4
"""Residuals below this count as noise, so noise-free data does not favour a model."""
OUTLIER_CAP_M = 0.01
"""Residuals are truncated here (or at 8 noise levels) when the models are compared."""
MAX_RADIUS_M = 3.0
"""A hinge farther than this from the path gives no revolute axis (the path is too straight)."""
HINGE_MAX_RADIUS_M = 1.5
"""For classification, a bend or turn about an axis farther than this is a line with play (a door's handle
is well under 1.5 m from its hinge)."""
MIN_SPREAD_M = 0.005
"""Less motion than this gives no axis at all."""
MIN_DECISION_TRAVEL_M = 0.03
"""Less travel than this, without a gripper turn, leaves the joint type undecided."""
MIN_ARC_DEG = 25.0
"""From positions alone, an arc shorter than this is no proof of a hinge (a slide's play bends its path)."""
MAX_GAP_SHARE = 0.25
"""Without orientations, a stretch without samples longer than this share of the travel leaves the type undecided."""
MIN_BEND_COVERAGE = 0.5
"""Such a stretch leaves the type undecided only when the samples left show a bend less than half as well as
an unbroken path would (`bend_coverage`): a gap between two long stretches hides nothing."""
MAX_HINGE_SIGMA_DEG = 10.0
"""A hinge found by `classify` whose direction is uncertain by more than this is reported as undecided."""
MIN_ROTATION_DEG = 3.0
"""A gripper turn smaller than this is not used (its axis would be noise)."""
TYPE_EVIDENCE = 13.8
"""chi-square with 2 degrees of freedom at 99.9 %: what the circle's 2 extra parameters must explain
beyond chance, in effective samples times noise variance, to count."""
_TURN_NOISE_RATIO = 4.0
_LINE_MISS_PER_SAGITTA = 0.298  # RMS distance of an evenly sampled shallow arc from its best line / sagitta
_MIN_TURN_CORRELATION = 0.9
_FULL_TRAVEL_M, _FULL_ARC_DEG = 0.05, 20.0
MAX_SIGMA_DEG = 90.0
"""A direction uncertain by more than this could be any direction: its sigma is reported as this."""
FIT_COVERAGE = 0.8
"""The share of the cells a fitted line or circle must explain: glitches are gone before the fits, so a fit
need not give up half the path (which let it follow the half that a part's play bent one way)."""
_JACKKNIFE_EVALUATIONS = 12  # a refit starts at the full fit's circle: a few steps reach its minimum
LEVEL_SIGMA_DEG = 1.5
"""How far furniture's hinges lean from vertical (doors) or horizontal (flaps, lids): building tolerance. With the
world's up direction given, a hinge's direction is pulled toward level by this prior (`level_hinge`)."""
LEVEL_GATE = 3.0
"""A hinge leaning more than this many combined standard deviations (its own and the prior's) is taken as built
that way, and its fit is kept."""


@dataclass(frozen=True)
class LineFit:
    origin: np.ndarray
    direction: np.ndarray
    rms_m: float
    inliers: np.ndarray


@dataclass(frozen=True)
class CircleFit:
    center: np.ndarray
    normal: np.ndarray
    radius_m: float
    rms_m: float
    inliers: np.ndarray


@dataclass(frozen=True)
class Turn:
    """The gripper's rotation: unit axis w (signed so the turn is positive), each cell's angle about it
    (rad), the turn's extent and the per-axis scatter off the axis (deg), and |correlation| of the
    angle with the travel along the line."""

    axis: np.ndarray
    angles: np.ndarray
    total_deg: float
    off_axis_deg: float
    correlation: float


@dataclass(frozen=True)
class Comparison:
    """Line against circle on the cells: evidence = (RSS_line - RSS_circle) / noise variance x n_eff / n;
    the noise variance sigma_m^2 (per axis), n_eff / n, and the circle's arc (deg)."""

    evidence: float
    sigma_m: float
    fraction: float
    arc_deg: float


def _confidence(inlier_fraction: float, motion: float, rms_m: float) -> float:
    """inlier fraction x motion (1 at full scale) x residual factor (0.5 at 2 mm RMS)."""
    return float(np.clip(inlier_fraction * min(motion, 1.0) / (1 + (rms_m / 0.002) ** 2), 0.0, 1.0))


def _fit_line(cells: np.ndarray) -> LineFit:
    (origin, direction, rms), inliers = fit_line_inliers(cells, FIT_COVERAGE)
    return LineFit(origin, direction, rms, inliers)


def _fit_circle(cells: np.ndarray) -> CircleFit | None:
    if len(cells) < 3:
        return None
    try:
        (center, normal, radius, rms), inliers = fit_circle_inliers(cells, FIT_COVERAGE)
    except ValueError:
        return None
    return CircleFit(center, normal, radius, rms, inliers)


def _line_vectors(points: np.ndarray, line: LineFit) -> np.ndarray:
    d = points - line.origin
    return d - np.outer(d @ line.direction, line.direction)


def _circle_vectors(points: np.ndarray, center: np.ndarray, normal: np.ndarray, radius: float) -> np.ndarray:
    """Each point minus its nearest point on the circle."""
    d = points - center
    in_plane = d - np.outer(d @ normal, normal)
    norms = np.maximum(np.linalg.norm(in_plane, axis=1, keepdims=True), 1e-12)
    return d - in_plane / norms * radius


def _arc_deg(points: np.ndarray, center: np.ndarray, normal: np.ndarray) -> float:
    u, v = plane_basis(normal)
    d = points - center
    return float(np.degrees(np.ptp(np.unwrap(np.arctan2(d @ v, d @ u)))))


def _rss(vectors: np.ndarray, cap_m: float) -> float:
    return float(np.sum(np.minimum(np.linalg.norm(vectors, axis=1), cap_m) ** 2))


def compare(path: PreparedPath, line: LineFit, circle: CircleFit | None) -> Comparison:
    """How much better the circle explains the cells than the line (`Comparison`)."""
    cells = path.cells
    floor = max(path.noise_m, NOISE_FLOOR_M)
    if circle is None:
        return Comparison(0.0, floor, effective_fraction(_line_vectors(cells, line)), 0.0)
    cap = max(OUTLIER_CAP_M, 8 * path.noise_m)
    circle_vectors = _circle_vectors(cells, circle.center, circle.normal, circle.radius_m)
    inliers = circle.inliers
    variance = _rss(circle_vectors[inliers], cap) / max(2 * inliers.sum() - 6, 1)
    sigma = max(float(np.sqrt(variance)), floor)
    fraction = effective_fraction(circle_vectors[inliers])
    gain = _rss(_line_vectors(cells, line), cap) - _rss(circle_vectors, cap)
    arc = _arc_deg(cells[inliers], circle.center, circle.normal)
    return Comparison(gain / sigma**2 * fraction, sigma, fraction, arc)


def gripper_turn(path: PreparedPath, line: LineFit) -> Turn | None:
    """The gripper's turn over the cells (`Turn`); None without orientations."""
    if path.rotvecs is None:
        return None
    rotvecs = path.rotvecs
    w = _rotation_axis(rotvecs)
    if rotvecs.sum(axis=0) @ w < 0:
        w = -w
    angles = rotvecs @ w
    low, high = np.percentile(angles, [2, 98]) if len(angles) >= 20 else (angles.min(), angles.max())
    off = np.sum((rotvecs - np.outer(angles, w)) ** 2, axis=1)
    off_axis = float(np.degrees(np.sqrt(np.median(off) / 1.386)))  # chi-square 2 dof median
    along = (path.cells - line.origin) @ line.direction
    correlation = 0.0
    if np.ptp(angles) > 0 and np.ptp(along) > 0:
        correlation = abs(float(np.corrcoef(angles, along)[0, 1]))
    return Turn(w, angles, float(np.degrees(high - low)), off_axis, correlation)


def _rotation_axis(rotvecs: np.ndarray) -> np.ndarray:
    """Least squares over R_k w = w (unit w, sign arbitrary), for rotations from the path's start
    (`trajectory_path.from_mean_start`): each weighs by its turn, so a subset near the start, as a
    jackknife refit may keep, still leans on the start that all cells agree on."""
    m = Rotation.from_rotvec(rotvecs).as_matrix() - np.eye(3)
    return np.linalg.eigh(np.einsum("kji,kjl->il", m, m))[1][:, 0]


def _turn_follows_travel(turn: Turn | None, path: PreparedPath) -> bool:
    """The gripper turned clearly (>= MIN_ROTATION_DEG and 4x its scatter), with the travel, about a
    hinge no farther than HINGE_MAX_RADIUS_M."""
    if turn is None or turn.total_deg < max(MIN_ROTATION_DEG, _TURN_NOISE_RATIO * turn.off_axis_deg):
        return False
    radius = path.travel_m / (2 * np.sin(np.radians(turn.total_deg) / 2))
    return turn.correlation >= _MIN_TURN_CORRELATION and radius <= HINGE_MAX_RADIUS_M


def rigid_turn_fit(cells: np.ndarray, w: np.ndarray, angles: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The positions as a point held rigidly while turning by `angles` (rad) about the unit axis w:
    x_k = c + Rot(theta_k) v at a constant height, c and v by linear least squares in the plane normal
    to w. Returns (centre at the cells' median height, radius, residual vectors)."""
    u, v = plane_basis(w)
    heights = cells @ w
    x = np.column_stack([cells @ u, cells @ v])
    cos, sin = np.cos(angles), np.sin(angles)
    ones, zeros = np.ones_like(cos), np.zeros_like(cos)
    design = np.vstack([np.column_stack([ones, zeros, cos, -sin]), np.column_stack([zeros, ones, sin, cos])])
    solution = np.linalg.lstsq(design, np.concatenate([x[:, 0], x[:, 1]]), rcond=None)[0]
    predicted = (design @ solution).reshape(2, -1).T
    level = float(np.median(heights))
    misfit = (x - predicted) @ np.vstack([u, v]) + np.outer(heights - level, w)
    center = solution[0] * u + solution[1] * v + level * w
    return center, float(np.hypot(solution[2], solution[3])), misfit


def _undecided(reason: str, **details: float) -> NoAxis:
    return NoAxis(f"joint type undecided: {reason}", {"undecided": True, **details})


def classify(path: PreparedPath, line: LineFit, circle: CircleFit | None, turn: Turn | None) -> JointType | NoAxis:
    """Prismatic, revolute, or NoAxis (undecided, with the reason).

    Revolute when the gripper turned with the travel about an axis within HINGE_MAX_RADIUS_M
    (`_turn_follows_travel`) and the positions do not contradict that turn (an arc that should bend the
    path by more than 4 TYPE_EVIDENCE must not leave it straight), or, without orientations, when the
    circle beats the line by more than TYPE_EVIDENCE (`compare`, which discounts correlated misfit such
    as play or tremor), lies within HINGE_MAX_RADIUS_M and spans MIN_ARC_DEG. Prismatic when the circle
    does not beat the line or is wider, or, with orientations that did not turn, bends less than
    MIN_ARC_DEG. Undecided below MIN_DECISION_TRAVEL_M of travel, for an arc too short to tell, for a
    line with a stretch of more than MAX_GAP_SHARE of its travel without samples whose samples left would
    show a bend less than MIN_BEND_COVERAGE as well as an unbroken path (positions only), and for
    contradicting evidence.
    """
    comparison = compare(path, line, circle)
    details = {"travel_m": path.travel_m, "misfit_m": comparison.sigma_m, "evidence": comparison.evidence}
    if _turn_follows_travel(turn, path):
        radius = path.travel_m / (2 * np.sin(np.radians(turn.total_deg) / 2))
        expected = _expected_evidence(path, turn, radius, comparison)
        if expected > 4 * TYPE_EVIDENCE and comparison.evidence <= TYPE_EVIDENCE:
            return _undecided(
                f"the gripper turned {turn.total_deg:.1f} deg with the travel, but the path does not bend like "
                f"the {radius:.2f} m arc that turn implies (a slipping grasp or a wobbling part)",
                turn_deg=turn.total_deg, **details)
        return JointType.REVOLUTE
    if path.travel_m < MIN_DECISION_TRAVEL_M:
        return _undecided(f"only {path.travel_m * 100:.1f} cm of travel and no clear gripper turn; need "
                          f"{MIN_DECISION_TRAVEL_M * 100:.0f} cm to tell a slide from a hinge", **details)
    if circle is None or comparison.evidence <= TYPE_EVIDENCE or circle.radius_m > HINGE_MAX_RADIUS_M:
        gap = path.largest_gap_m
        coverage = bend_coverage((path.cells - line.origin) @ line.direction)
        if turn is None and gap > MAX_GAP_SHARE * path.travel_m and coverage < MIN_BEND_COVERAGE:
            return _undecided(
                f"{gap * 100:.0f} cm of the {path.travel_m * 100:.0f} cm path has no samples (tracking lost?), and "
                f"the samples left show a hinge's bend {coverage:.0%} as well as an unbroken path: without "
                "orientations a line through them proves nothing", gap_m=gap, bend_coverage=coverage, **details)
        return JointType.PRISMATIC
    details.update(arc_deg=comparison.arc_deg, radius_m=circle.radius_m)
    if turn is not None:  # a hinge turns the handle with it; this one did not
        if comparison.arc_deg < MIN_ARC_DEG:
            return JointType.PRISMATIC  # a shallow bend: the part's play
        return _undecided(
            f"the path bends like a {comparison.arc_deg:.0f} deg arc but the gripper did not turn with it "
            f"({turn.total_deg:.1f} deg, correlation {turn.correlation:.2f}): a loose grasp?",
            turn_deg=turn.total_deg, **details)
    if comparison.arc_deg < MIN_ARC_DEG:
        return _undecided(
            f"the path bends like a {comparison.arc_deg:.0f} deg arc of radius {circle.radius_m:.2f} m, too short "
            f"an arc (< {MIN_ARC_DEG:.0f} deg) to tell a hinge from a wobbling slide; pull further or record "
            "orientations", **details)
    return JointType.REVOLUTE


def _expected_evidence(path: PreparedPath, turn: Turn, radius_m: float, comparison: Comparison) -> float:
    """The evidence `compare` would find if the cells lay on the arc the turn implies: each cell's
    distance from the chord at its turn angle, less their mean (the best line's offset), capped."""
    total = np.radians(turn.total_deg)
    angles = np.clip(turn.angles - np.percentile(turn.angles, 2 if len(turn.angles) >= 20 else 0), 0, total)
    bow = radius_m * (np.cos(angles - total / 2) - np.cos(total / 2))
    cap = max(OUTLIER_CAP_M, 8 * path.noise_m)
    return float(np.sum(np.minimum(np.abs(bow - bow.mean()), cap) ** 2) / comparison.sigma_m**2 * comparison.fraction)


def fit_trajectory(
    positions: np.ndarray, quaternions: np.ndarray | None = None, joint: JointType | None = None, *,
    times: np.ndarray | None = None, up: np.ndarray | None = None,
) -> AxisResult:
    """The joint axis from gripper positions (N,3) and optional orientations (N,4, xyzw), oldest first
    (or in any order with `times` (N,) s, which sorts them).

    Prismatic: a robust line through the path's cells; direction along the motion (first -> last).
    Revolute: the direction from the circle's normal and the gripper's turn, each weighted by its
    variance (`_hinge_direction`); the centre from a circle in the plane normal to it, or with a turn from
    the rigid turn model (`rigid_turn_fit`) when its misfit is within twice the circle's, plus what
    the turn's own scatter explains, plus 1 mm (a slipping grasp breaks it). Opening is a positive
    rotation about the direction; origin = the axis point level with the handle; radius_m = circle
    radius. `direction_sigma_deg` is the direction's standard deviation. With the world's `up` (3,) in the
    samples' frame, a hinge is levelled toward vertical or horizontal by `level_hinge` (furniture is built level).

    Joint type when `joint` is None: `classify`, which may answer NoAxis ("joint type undecided: ...",
    details["undecided"] = True), also for a hinge whose direction is uncertain by more than
    MAX_HINGE_SIGMA_DEG. NoAxis also for fewer than 3 samples, non-finite values, less than MIN_SPREAD_M
    of motion, or no fit.
    """
    return _fit(positions, quaternions, joint, times, up)[0]


def fit_trajectory_report(
    positions: np.ndarray, quaternions: np.ndarray | None = None, joint: JointType | None = None, *,
    times: np.ndarray | None = None, up: np.ndarray | None = None,
) -> dict:
    """`fit_trajectory` as a JSON-ready dict: the axis (`Axis.to_dict`: joint_type, origin, direction,
    radius_m, residual_m, confidence, direction_sigma_deg) or its reason and details, with the path's
    own noise (noise_m, per axis), its travel (travel_m) and, for a hinge, the arc it swept (arc_deg)."""
    result, path = _fit(positions, quaternions, joint, times, up)
    data = {"joint_type": None, "origin": None, "direction": None, "radius_m": None, "residual_m": None,
            "confidence": None, "direction_sigma_deg": None, "noise_m": None, "travel_m": None, "arc_deg": None}
    if path is not None:
        data.update(noise_m=path.noise_m, travel_m=path.travel_m)
    if isinstance(result, NoAxis):
        details = {k: float(v) if isinstance(v, np.floating) else v for k, v in result.details.items()}
        return {**data, "arc_deg": details.get("arc_deg"), "reason": result.reason, "details": details}
    data.update(result.to_dict())
    if result.joint_type is JointType.REVOLUTE:
        data["arc_deg"] = _arc_deg(path.cells, result.origin, result.direction)
    return data


def _fit(positions, quaternions, joint, times, up) -> tuple[AxisResult, PreparedPath | None]:
    """`fit_trajectory`'s answer and the prepared path (None when the samples were refused)."""
    checked = _checked(positions, quaternions, times)
    if isinstance(checked, NoAxis):
        return checked, None
    positions, quaternions = checked
    centred = positions - positions.mean(axis=0)
    spread = float(np.ptp(centred @ np.linalg.svd(centred)[2][0]))
    if spread < MIN_SPREAD_M:
        return NoAxis(f"not enough motion yet: {spread * 1000:.1f} mm of {MIN_SPREAD_M * 1000:.0f} mm",
                      {"spread_m": spread}), None
    path = prepare_path(positions, quaternions)
    if len(path.cells) < 3:  # the spread was a glitch: what is left stands still
        return NoAxis(f"not enough motion yet: the samples left after dropping glitches fill {len(path.cells)} "
                      f"place(s) {path.cell_m * 1000:.0f} mm apart", {"travel_m": path.travel_m}), path
    line = _fit_line(path.cells)
    circle = _fit_circle(path.cells) if joint is not JointType.PRISMATIC else None
    turn = gripper_turn(path, line)
    if joint is None:
        decided = classify(path, line, circle, turn)
        if isinstance(decided, NoAxis):
            return decided, path
        if decided is JointType.REVOLUTE:
            return _sure_hinge(revolute_axis(path, circle, turn, up), path, line, circle), path
        joint = decided
    if joint is JointType.REVOLUTE:
        return revolute_axis(path, circle, turn, up), path
    return prismatic_axis(path, line), path


def _sure_hinge(axis: AxisResult, path: PreparedPath, line: LineFit, circle: CircleFit | None) -> AxisResult:
    """A hinge the classification found, or undecided when its direction is uncertain by more than
    MAX_HINGE_SIGMA_DEG (a short arc bent by play, a turn about a wandering axis): such a call is more
    often a wrong joint type than a useful axis."""
    sigma = axis.direction_sigma_deg if isinstance(axis, Axis) else None
    if sigma is None or sigma <= MAX_HINGE_SIGMA_DEG:
        return axis
    arc = _arc_deg(path.cells, axis.origin, axis.direction)
    comparison = compare(path, line, circle)
    return _undecided(
        f"a hinge, but its direction is uncertain by {sigma:.0f} deg (over {MAX_HINGE_SIGMA_DEG:.0f} deg) after a "
        f"{arc:.0f} deg arc: too short an arc or too much play to trust; pull further or record orientations",
        travel_m=path.travel_m, misfit_m=comparison.sigma_m, evidence=comparison.evidence, arc_deg=arc,
        direction_sigma_deg=sigma)


def _checked(positions, quaternions, times) -> tuple[np.ndarray, np.ndarray | None] | NoAxis:
    """Validated arrays in time order, or NoAxis naming what is wrong."""
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
    if times is not None:
        times = np.asarray(times, float)
        if times.shape != (len(positions),) or not np.all(np.isfinite(times)):
            return NoAxis(f"times must be {len(positions)} finite values, got shape {times.shape}")
        order = np.argsort(times, kind="stable")
        positions, quaternions = positions[order], None if quaternions is None else quaternions[order]
    return positions, quaternions


def prismatic_axis(path: PreparedPath, line: LineFit) -> Axis:
    """The line as a prismatic axis: origin = the first cell's foot on the line, direction along the motion."""
    cells, inliers = path.cells, line.inliers
    direction = line.direction
    start = line.origin + ((cells[0] - line.origin) @ direction) * direction
    along = (cells - start) @ direction
    if _trend(along, inliers) < 0:
        direction = -direction

    def refit(keep: np.ndarray) -> np.ndarray | None:
        chosen = cells[inliers & keep]
        return None if len(chosen) < 2 else np.linalg.svd(chosen - chosen.mean(axis=0))[2][0]

    sigma = jackknife_sigma_deg(direction, refit, len(cells))
    motion = float(np.ptp(along[inliers])) / _FULL_TRAVEL_M
    return Axis(
        JointType.PRISMATIC, start, direction, confidence=_confidence(inliers.mean(), motion, line.rms_m),
        residual_m=line.rms_m, direction_sigma_deg=None if np.isnan(sigma) else sigma,
    )


def _trend(values: np.ndarray, mask: np.ndarray) -> float:
    """Sign-bearing trend of `values` with the cell order, over the masked cells."""
    order = np.arange(len(values), dtype=float)[mask]
    return float(np.sum((order - order.mean()) * values[mask]))


def revolute_axis(path: PreparedPath, circle: CircleFit | None, turn: Turn | None,
                  up: np.ndarray | None = None) -> AxisResult:
    """The hinge (`fit_trajectory`), or NoAxis when no circle fits or it is wider than MAX_RADIUS_M. With the
    world's `up`, a direction known to MAX_HINGE_SIGMA_DEG is levelled (`level_hinge`) before the centre is fitted."""
    use_turn = turn is not None and turn.total_deg >= MIN_ROTATION_DEG
    if circle is None and not use_turn:
        return NoAxis("no hinge circle fits the gripper path: the points are collinear")
    direction, sigma = _hinge_direction(path, circle, turn if use_turn else None)
    if up is not None and sigma is not None and sigma <= MAX_HINGE_SIGMA_DEG:
        direction, sigma = level_hinge(direction, sigma, up)
    cells = path.cells
    flat = cells - np.outer(cells @ direction - np.median(cells @ direction), direction)
    planar = _fit_circle(flat)
    if planar is None:
        return NoAxis("no hinge circle fits the gripper path: the points are collinear")
    center, radius, inliers = planar.center, planar.radius_m, planar.inliers
    if use_turn:
        rigid_center, rigid_radius, misfit = rigid_turn_fit(cells, direction, path.rotvecs @ direction)
        circle_rms = float(np.sqrt(np.mean(circle_residuals(flat, center, direction, radius)[inliers] ** 2)))
        in_plane = misfit - np.outer(misfit @ direction, direction)
        rigid_rms = float(np.sqrt(np.mean(np.sum(in_plane[inliers] ** 2, axis=1))))
        turn_noise_m = rigid_radius * np.radians(turn.off_axis_deg) * np.sqrt(2)  # the turn's own scatter
        if rigid_rms <= 2 * circle_rms + turn_noise_m + 1e-3:
            center, radius = rigid_center, rigid_radius
    if radius > MAX_RADIUS_M:
        return NoAxis(f"the gripper path is too straight to locate a hinge: circle radius {radius:.1f} m",
                      {"radius_m": radius})
    u, v = plane_basis(direction)
    d = cells - center
    angles = np.unwrap(np.arctan2(d @ v, d @ u))
    if not use_turn and _trend(angles, inliers) < 0:
        direction = -direction
    residuals = circle_residuals(cells, center, direction, radius)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    swept_deg = float(np.degrees(np.ptp(angles[inliers])))
    return Axis(
        JointType.REVOLUTE, center, direction, confidence=_confidence(inliers.mean(), swept_deg / _FULL_ARC_DEG, rms),
        residual_m=rms, radius_m=radius, direction_sigma_deg=sigma,
    )


def _hinge_direction(
    path: PreparedPath, circle: CircleFit | None, turn: Turn | None
) -> tuple[np.ndarray, float | None]:
    """The hinge direction and its standard deviation (deg): the circle's normal and the turn's axis
    weighted by their variances; when they disagree by more than 3 combined standard deviations, the
    surer one (its sigma at least a third of the disagreement). Each variance is the block jackknife's
    plus what the path shows of a bias the jackknife misses: for the circle the plane's tilt error
    (`plane_tilt_deg`), for the turn its scatter about other axes over the turn (`turn_play_deg`)."""
    cells, candidates = path.cells, []
    if turn is not None:
        rotvecs = path.rotvecs

        def refit_turn(keep: np.ndarray) -> np.ndarray | None:
            return _rotation_axis(rotvecs[keep]) if keep.sum() >= 2 else None

        candidates.append((turn.axis, float(np.hypot(jackknife_sigma_deg(turn.axis, refit_turn, len(cells)),
                                                     turn_play_deg(turn.off_axis_deg, turn.angles)))))
    if circle is not None:
        normal = circle.normal if turn is None or circle.normal @ turn.axis >= 0 else -circle.normal

        def refit_circle(keep: np.ndarray) -> np.ndarray | None:
            chosen = cells[circle.inliers & keep]
            if len(chosen) < 4:
                return None
            return refine_circle(chosen, circle.center, normal, circle.radius_m, _JACKKNIFE_EVALUATIONS)[1]

        candidates.append((normal, float(np.hypot(jackknife_sigma_deg(normal, refit_circle, len(cells)),
                                                  plane_tilt_deg(cells[circle.inliers], normal)))))
    if len(candidates) == 1 or any(np.isnan(s) for _, s in candidates):
        direction, sigma = candidates[0]
        return direction, None if np.isnan(sigma) else min(sigma, MAX_SIGMA_DEG)
    (a, sa), (b, sb) = candidates
    if not np.isfinite(min(sa, sb)):
        return (a, MAX_SIGMA_DEG) if sa <= sb else (b, MAX_SIGMA_DEG)
    disagreement = float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))
    if disagreement > 3 * np.hypot(sa, sb):
        direction, sigma = (a, sa) if sa <= sb else (b, sb)
        return direction, min(max(sigma, disagreement / 3), MAX_SIGMA_DEG)
    combined = a / sa**2 + b / sb**2
    return combined / np.linalg.norm(combined), min(float(1 / np.sqrt(1 / sa**2 + 1 / sb**2)), MAX_SIGMA_DEG)


def level_hinge(direction: np.ndarray, sigma_deg: float, up: np.ndarray) -> tuple[np.ndarray, float]:
    """A hinge direction and its sigma (deg) with the prior that furniture is built level: the hinge leans from
    vertical (within 45 deg of `up`) or from horizontal by a Gaussian of LEVEL_SIGMA_DEG. The lean shrinks by
    prior^2 / (prior^2 + sigma^2) (the posterior's mode) and its sigma to the posterior's; a horizontal hinge's
    heading keeps the fit's and its sigma, so the sigma reported is the RMS of the two. A lean beyond LEVEL_GATE
    combined sigmas is kept as measured."""
    up = up / np.linalg.norm(up)
    height = float(direction @ up)
    vertical = abs(height) >= np.sqrt(0.5)
    target = np.sign(height) * up if vertical else (direction - height * up) / np.linalg.norm(direction - height * up)
    lean = float(np.arccos(np.clip(direction @ target, -1.0, 1.0)))
    combined = float(np.hypot(sigma_deg, LEVEL_SIGMA_DEG))
    if lean < 1e-9 or np.degrees(lean) > LEVEL_GATE * combined:
        return direction, sigma_deg
    turn_axis = np.cross(target, direction)
    kept = LEVEL_SIGMA_DEG**2 / combined**2
    levelled = Rotation.from_rotvec(turn_axis / np.linalg.norm(turn_axis) * lean * kept).apply(target)
    lean_sigma = sigma_deg * LEVEL_SIGMA_DEG / combined
    return levelled, lean_sigma if vertical else float(np.sqrt((sigma_deg**2 + lean_sigma**2) / 2))


class TrajectoryEstimator(AxisEstimator):
    """The axis from the gripper poses of the window (forward kinematics), via `fit_trajectory`."""

    name = "trajectory"
    use_gripper = True

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
