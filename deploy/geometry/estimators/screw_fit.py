"""The joint that best explains a part's registered rigid motions: prismatic or revolute, chosen by BIC.

Stateless numpy functions (base frame, metres). `poses` (K,4,4) are the part's motions relative to the
window start; `sample` (M,3) are model points of the part at the start and `moved` (K,M,3) the same
points after each motion. A track is a pair (positions (K+1,3) or (N,3), noise_m): the part's centroid
at the start and after each motion, or the gripper's path; each track weighs 1 / its noise in the fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.screw_config import ScrewConfig
from deploy.geometry.estimators.trajectory_fit import plane_basis
from deploy.geometry.estimators.trajectory_path import jackknife_sigma_deg
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis

Track = tuple[np.ndarray, float]

_MODEL_POINTS = 200
_FULL_FITNESS = 0.9
_FULL_TRAVEL_M, _FULL_ROTATION_DEG = 0.05, 10.0
_HALF_CONFIDENCE_RMS_M = 0.002
_HALF_CONFIDENCE_SIGMA_DEG = 3.0
_JACKKNIFE_BLOCKS = 3  # stretches of a window a drawer's direction is refitted without (`direction_sigma_deg`)
_MAX_HINGE_TILT_DEG = 30.0  # a hinge lies in its door's plane: within this, w is projected into the plate
_FRONT_CONE_DEG, _FRONT_SLAB_M, _MIN_FRONT_NORMALS = 20.0, 0.01, 50
_FRONT_POINTS_PER_SAMPLE = 25  # front points that count as one independent sample of the plane
FREE_DIRECTION_EVIDENCE = 13.8
"""chi-square with 2 degrees of freedom at 99.9 %: how much better a free drawer direction must explain the
tracks than the front's normal (in track noise variances) to be used instead."""


@dataclass(frozen=True)
class JointFit:
    """A fitted joint: the line through `point` along unit `direction`, the RMS distance (m) between the
    registered and the joint's positions of the model points, the fit's BIC, the direction's standard
    deviation (deg, None when not measured) and whether the direction is a drawer front's normal."""

    direction: np.ndarray
    point: np.ndarray
    rms_m: float
    bic: float
    sigma_deg: float | None = None
    from_front: bool = False


def fit_screw_joint(
    poses: np.ndarray, start: np.ndarray, latest_centre: np.ndarray, fitness: float, joint: JointType | None,
    config: ScrewConfig, grip_at_poses: np.ndarray | None = None, grip_path: np.ndarray | None = None,
    surface: tuple[np.ndarray, np.ndarray] | None = None,
) -> AxisResult:
    """The joint axis from the motions `poses` (K,4,4) of the window-start points `start` (M,3).

    `latest_centre` is the centroid of the latest frame's part, `fitness` the lowest registration
    fitness of the frames used. The gripper's positions, when known: `grip_at_poses` (K+1,3) at the
    start and after each motion (for a hinge, which needs the turns), `grip_path` (N,3) in every frame
    of the window (for a line). `surface`: points of the part at the start and their unit normals, for a
    drawer's front (`fit_prismatic`). NoAxis when the part moved less than config.min_travel_m and turned
    less than config.min_rotation_deg.

    Prismatic (`fit_prismatic`): origin = centroid of the model points at the window start. Revolute
    (`fit_revolute`): origin = the axis point nearest `latest_centre`, radius_m = distance from it to
    the axis. residual_m = the fit's RMS; confidence = fitness (1 from 90 %) x motion (1 from 5 cm or
    10 deg) x 1 / (1 + (residual / 2 mm)^2), and for a drawer whose direction comes from its motion
    alone (no front face), x 1 / (1 + (sigma / 3 deg)^2) with sigma its standard deviation
    (direction_sigma_deg). direction_sigma_deg is set for a front's normal and a hinge too (`fit_prismatic`,
    `fit_revolute`), without touching the confidence.

    Joint type when `joint` is None: BIC = n ln(rms^2 + sigma0^2) + k ln n with n = 6 per pose (what a
    registration measures), k = poses + 2 (prismatic) or poses + 4 (revolute), sigma0 =
    config.noise_floor_m, plus with the gripper's path the same for its miss of the joint's line or circle
    (`grip_bic`); the lower wins, except that a revolute axis farther than config.max_radius_m from the part
    means prismatic.
    """
    sample = start[np.linspace(0, len(start) - 1, min(len(start), _MODEL_POINTS)).astype(int)]
    moved = np.einsum("kij,mj->kmi", poses[:, :3, :3], sample) + poses[:, None, :3, 3]
    centroid = sample.mean(axis=0)
    travel_m = float(np.max(np.linalg.norm(moved.mean(axis=1) - centroid, axis=1)))
    rotation_deg = float(np.degrees(np.max(Rotation.from_matrix(poses[:, :3, :3]).magnitude())))
    if travel_m < config.min_travel_m and rotation_deg < config.min_rotation_deg:
        return NoAxis(
            f"not enough motion yet: {travel_m * 1000:.1f} mm of {config.min_travel_m * 1000:.0f} mm "
            f"and {rotation_deg:.1f} deg of {config.min_rotation_deg:.0f} deg",
            {"travel_m": travel_m, "rotation_deg": rotation_deg},
        )
    fits = {}
    if joint is not JointType.REVOLUTE:
        tracks = part_and_grip_tracks(sample, moved, grip_path, config.part_noise_m, config.grip_noise_m)
        fits[JointType.PRISMATIC] = fit_prismatic(sample, moved, tracks, config.grip_gate_m, config.noise_floor_m,
                                                  surface)
    if joint is not JointType.PRISMATIC:
        tracks = part_and_grip_tracks(sample, moved, grip_at_poses, config.part_noise_m, config.grip_noise_m)
        path = None if grip_path is None else (grip_path, config.grip_noise_m)
        fits[JointType.REVOLUTE] = fit_revolute(
            poses[:, :3, :3], sample, moved, tracks, config.grip_gate_m, config.noise_floor_m,
            config.part_noise_m, path)
    radius_m = distance_to_line(latest_centre, fits[JointType.REVOLUTE]) if JointType.REVOLUTE in fits else 0.0
    far = radius_m > config.max_radius_m
    if joint is None:
        grip = {j: grip_bic(grip_path, fits[j], j, config.grip_noise_m) for j in fits}
        joint = JointType.PRISMATIC if far else min(fits, key=lambda j: fits[j].bic + grip[j])
    elif joint is JointType.REVOLUTE and far:
        return NoAxis(
            f"the motion is too straight to locate a hinge: the fitted axis is more than "
            f"{config.max_radius_m:.1f} m from the moving part",
            {"radius_m": radius_m},
        )
    fit = fits[joint]
    motion = min(1.0, max(travel_m / _FULL_TRAVEL_M, rotation_deg / _FULL_ROTATION_DEG))
    trust = min(fitness, _FULL_FITNESS) / _FULL_FITNESS
    confidence = float(np.clip(trust * motion / (1 + (fit.rms_m / _HALF_CONFIDENCE_RMS_M) ** 2), 0.0, 1.0))
    if joint is JointType.PRISMATIC:
        if fit.sigma_deg is not None and not fit.from_front:  # a direction the motion alone pins down loosely
            confidence /= 1 + (fit.sigma_deg / _HALF_CONFIDENCE_SIGMA_DEG) ** 2
        return Axis(joint, centroid, fit.direction, confidence=confidence, residual_m=fit.rms_m,
                    direction_sigma_deg=fit.sigma_deg)
    origin = fit.point + ((latest_centre - fit.point) @ fit.direction) * fit.direction
    return Axis(joint, origin, fit.direction, confidence=confidence, residual_m=fit.rms_m, radius_m=radius_m,
                direction_sigma_deg=fit.sigma_deg)


def part_and_grip_tracks(
    sample: np.ndarray, moved: np.ndarray, grip: np.ndarray | None, part_noise_m: float, grip_noise_m: float
) -> list[Track]:
    """The tracks to fit a joint to: the part's centroid at the start and after each motion, and the
    gripper's positions `grip` when given."""
    tracks = [(np.vstack([sample.mean(axis=0), moved.mean(axis=1)]), part_noise_m)]
    return tracks if grip is None else tracks + [(grip, grip_noise_m)]


def fit_prismatic(
    sample: np.ndarray, moved: np.ndarray, tracks: list[Track], grip_gate_m: float, noise_floor_m: float,
    surface: tuple[np.ndarray, np.ndarray] | None = None,
) -> JointFit:
    """Points move by s_k d: d = principal direction of the tracks' positions (`principal_direction`),
    signed along the motion; a second (gripper) track farther than `grip_gate_m` RMS from its line is
    left out. The line passes through the model points' centroid.

    From the part alone (no gripper track), with its `surface` (points (M,3) and their unit normals),
    d is the normal of its faces within 20 deg of that direction (`front_face`: a drawer's front)
    unless the free direction
    explains the tracks better by more than FREE_DIRECTION_EVIDENCE (`free_direction_evidence`):
    registration measures a drawer's motion along its front's normal well and barely across it (a
    plate slides along itself), so a drift across the front is read as motion only when the tracks
    show it beyond their scatter. sigma_deg: the free direction's standard deviation from what the tracks
    show (`direction_sigma_deg`), or for the front's normal hypot(the plane fit's standard error, the
    standard error with which `free_direction_evidence` resolves a free direction): the runners may be
    slanted from the front's normal by as much as that test cannot tell from the front's normal.
    """
    d = principal_direction(tracks)
    if len(tracks) > 1 and line_miss(tracks[1][0], d) > grip_gate_m:
        tracks = tracks[:1]
        d = principal_direction(tracks)
    face = front_face(*surface, d) if surface is not None and len(tracks) == 1 else None
    evidence, resolution_deg = free_direction_evidence(tracks, d, d if face is None else face[0])
    from_front = face is not None and evidence <= FREE_DIRECTION_EVIDENCE
    if from_front:
        d, sigma_deg = face[0], float(np.hypot(face[1], resolution_deg or 0.0))
    else:
        sigma_deg = direction_sigma_deg(tracks, d)
    shifts = moved.mean(axis=1) - sample.mean(axis=0)
    travel = shifts @ d
    if travel[np.argmax(np.abs(travel))] < 0:
        d, travel = -d, -travel
    predicted = sample[None] + travel[:, None, None] * d
    rms = float(np.sqrt(np.mean(np.sum((moved - predicted) ** 2, axis=2))))
    return JointFit(d, sample.mean(axis=0), rms, bic(rms, 6 * len(moved), len(moved) + 2, noise_floor_m), sigma_deg,
                    from_front)


def front_face(points: np.ndarray, normals: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The unit normal (signed like `direction`) of the part's largest face turned toward `direction`
    and its standard error (deg): of the points whose surface normals lie within 20 deg of it, those in
    the most populated 1 cm slab along their mean normal (one face, not the parallel handle or back
    panel), then a plane through them by trimmed PCA (`_trimmed_plane`). The plane of many points, not
    the mean of the noisy local normals, which lean toward the camera's rays. The standard error is the
    plane's RMS thickness over its narrower RMS extent, over the square root of the points kept per
    _FRONT_POINTS_PER_SAMPLE (a depth camera's errors are shared by neighbouring pixels). None with
    fewer than 50 such points."""
    normals = np.asarray(normals, float)
    signed = normals * np.where(normals @ direction < 0, -1.0, 1.0)[:, None]
    facing = signed @ direction >= np.cos(np.radians(_FRONT_CONE_DEG))
    if facing.sum() < _MIN_FRONT_NORMALS:
        return None
    points = np.asarray(points, float)[facing]
    mean = signed[facing].sum(axis=0)
    offsets = points @ (mean / np.linalg.norm(mean))
    bins = np.floor((offsets - offsets.min()) / _FRONT_SLAB_M).astype(int)
    slab = np.abs(offsets - (offsets.min() + (np.bincount(bins).argmax() + 0.5) * _FRONT_SLAB_M)) <= _FRONT_SLAB_M
    if slab.sum() < _MIN_FRONT_NORMALS:
        return None
    normal, spread, kept = _trimmed_plane(points[slab])
    samples = max(kept / _FRONT_POINTS_PER_SAMPLE, 1.0)
    sigma_deg = float(np.degrees(spread[2] / max(spread[1], 1e-12) / np.sqrt(samples)))
    return (normal if normal @ direction >= 0 else -normal), sigma_deg


def _trimmed_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(unit normal, singular values, points kept) of the plane most of `points` lie on: three rounds of
    PCA, each of the points within 3 median distances (at least 2 mm) of the last plane."""
    kept = points
    for _ in range(3):
        centre = kept.mean(axis=0)
        _, spread, axes = np.linalg.svd(kept - centre, full_matrices=False)
        distance = np.abs((points - centre) @ axes[2])
        kept = points[distance <= max(3 * np.median(distance), 0.002)]
    return axes[2], spread, len(kept)


def free_direction_evidence(tracks: list[Track], free: np.ndarray, fixed: np.ndarray) -> tuple[float, float | None]:
    """How much better the line along `free` explains the tracks (each about its own mean, weighted by
    1 / its noise relative to the first's) than the line along `fixed`: (RSS_fixed - RSS_free) / s^2,
    s^2 = RSS_free / its degrees of freedom, at least the first track's noise squared (a registration's
    slide across a front is not white: it drifts with the opening, so the track's own scatter
    understates it). Also the free direction's standard error at that noise (deg; None with too few positions):
    how finely the test resolves a slant."""
    weight0 = tracks[0][1]
    rss_free = rss_fixed = spread = 0.0
    count = 0
    for positions, sigma in tracks:
        centred = (positions - positions.mean(axis=0)) * (weight0 / sigma)
        total = float(np.sum(centred**2))
        rss_free += total - float(np.sum((centred @ free) ** 2))
        rss_fixed += total - float(np.sum((centred @ fixed) ** 2))
        spread += float(np.sum((centred @ free) ** 2))
        count += len(positions)
    dof = 2 * (count - len(tracks)) - 2
    if dof < 1 or spread <= 0:
        return 0.0, None
    variance = max(rss_free / dof, weight0**2)
    return (rss_fixed - rss_free) / variance, float(np.degrees(np.sqrt(variance / spread)))


def direction_sigma_deg(tracks: list[Track], direction: np.ndarray) -> float | None:
    """RMS angle error (deg, both components across the line) of the line `direction` fitted to the tracks
    (`principal_direction`), from what they show: the larger of the propagated scatter (each track's own
    residual variance about the line, through the fit's weights) and a block jackknife, which also sees what
    is not white (a registration that drifts with the opening, a grasp that shifts). The jackknife's blocks
    are stretches of equal travel along the line (the first track's; each track cut at the same share of its
    positions), so that a window whose motion ends early is not refitted from its rest alone. None with too
    few positions to tell. An RMS sigma: 2 sigma holds 98 % of a Gaussian error's two components."""
    weights, spreads, residuals = [], [], []
    for positions, sigma in tracks:
        centred = positions - positions.mean(axis=0)
        along = float(np.sum((centred @ direction) ** 2))
        weights.append((tracks[0][1] / sigma) ** 2)
        spreads.append(along)
        residuals.append(max(float(np.sum(centred**2)) - along, 0.0))
    w, a, r = np.array(weights), np.array(spreads), np.array(residuals)
    information = float(w @ a)
    if information <= 0 or sum(len(p) for p, _ in tracks) < 3:
        return None
    leverage = w * a / information  # the share of the direction's two degrees of freedom each track takes
    dof = np.array([2 * (len(p) - 1) for p, _ in tracks]) - 2 * leverage
    variance = r / np.maximum(dof, 1.0)  # per axis across the line
    scatter = float(np.degrees(np.sqrt(2 * np.sum(w**2 * variance * a)) / information))
    n = len(tracks[0][0])
    replicates = []
    for block in travel_blocks(tracks[0][0] @ direction):
        keep = np.ones(n, bool)
        keep[block] = False
        kept = [(p[keep[np.arange(len(p)) * n // len(p)]], sigma) for p, sigma in tracks]
        kept = [(p, sigma) for p, sigma in kept if len(p) >= 2]
        if kept:
            d = principal_direction(kept)
            replicates.append(d if d @ direction >= 0 else -d)
    if len(replicates) < 2:
        return scatter
    rep = np.array(replicates)
    jackknife = np.sqrt(np.sum((rep - rep.mean(axis=0)) ** 2) * (len(rep) - 1) / len(rep))
    return max(scatter, float(np.degrees(jackknife)))


def travel_blocks(along: np.ndarray, count: int = _JACKKNIFE_BLOCKS) -> list[np.ndarray]:
    """Contiguous index blocks of the positions `along` a line (in order) that each cover an equal share
    of the travel (the summed steps), at most `count` and one position or more each."""
    steps = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(along)))])
    if len(along) < 2 * count or steps[-1] <= 0:
        count = len(along) // 2
    edges = np.unique(np.searchsorted(steps, np.linspace(0.0, steps[-1], count + 1)[1:-1], side="right"))
    return [block for block in np.split(np.arange(len(along)), edges) if len(block)]


def fit_revolute(
    rotations: np.ndarray, sample: np.ndarray, moved: np.ndarray, tracks: list[Track], grip_gate_m: float,
    noise_floor_m: float, part_noise_m: float = 0.003, path: Track | None = None,
) -> JointFit:
    """Rotation about the line (w, a), from the registered `rotations` (K,3,3) and the gripper's `path`.

    w: least squares over R_k w = w and, with the gripper's path (positions (N,3), noise), over (p_n - mean) . w
    = 0 (the held handle runs in a plane normal to the hinge), each weighted by its noise (`hinge_direction`);
    without the path, projected into the plane of a plate-shaped part (a door panel) when within 30 deg of it,
    since a hinge lies in its door's plane and the rotation about a plate's normal is what registration
    measures worst. Signed so the motion turns positively. The turns are the rotations' angles about w (what
    registration measures best). a: the centre of the circles the tracks run through at those turns
    (`circle_centre`), level with the model points. A gripper path missing every circle about w by more than
    `grip_gate_m` RMS (`circle_miss`: the grasp slipped) is left out of w, and a second (gripper) track missing
    its circle at the turns by more than that is left out of a.
    sigma_deg: the larger of the misfit's standard error (`hinge_scatter_deg`; for a w projected into the
    plate, with the plate normal's error in quadrature; with the path, from both) and the block jackknife of w
    over the rotations.
    """
    plate_fit = plate_normal(sample)
    plate = None if plate_fit is None else plate_fit[0]
    rotation_var = rotation_variance(rotations, sample, part_noise_m)
    if path is not None and circle_miss(path[0], hinge_direction(rotations, plate, rotation_var, path)) > grip_gate_m:
        path = None
    w, a, misses, turns = _hinge(rotations, sample, tracks, plate, rotation_var, path)
    if len(tracks) > 1 and misses[1] > grip_gate_m:
        w, a, _, turns = _hinge(rotations, sample, tracks[:1], plate, rotation_var, path)
    predicted = np.einsum("kij,mj->kmi", turns, sample - a) + a
    rms = float(np.sqrt(np.mean(np.sum((moved - predicted) ** 2, axis=2))))
    in_plate = plate_fit is not None and abs(w @ plate) < 1e-9  # in the plate: w turns with the plate's normal
    kept_in = plate if in_plate else None
    if path is not None:
        scatter = _information_sigma_deg(hinge_information(rotations, rotation_var, path), w, kept_in)
    else:
        scatter = hinge_scatter_deg(rotations, w, kept_in)
    if scatter is not None and in_plate:
        scatter = float(np.hypot(scatter, plate_fit[1]))
    jackknife = jackknife_sigma_deg(
        w, lambda keep: hinge_direction(rotations[keep], plate, rotation_var, path), len(rotations))
    sigma = None if scatter is None else max(scatter, 0.0 if np.isnan(jackknife) else jackknife)
    return JointFit(w, a, rms, bic(rms, 6 * len(moved), len(moved) + 4, noise_floor_m), sigma)


def _hinge(
    rotations: np.ndarray, sample: np.ndarray, tracks: list[Track], plate: np.ndarray | None, rotation_var: float,
    path: Track | None,
) -> tuple[np.ndarray, np.ndarray, list[float], np.ndarray]:
    """(w signed to turn positively, a, each track's circle miss, the turns about w) of `fit_revolute`."""
    w = hinge_direction(rotations, plate, rotation_var, path)
    rotvecs = Rotation.from_matrix(rotations).as_rotvec()
    if rotvecs.sum(axis=0) @ w < 0:
        w = -w
    turns = Rotation.from_rotvec(np.outer(rotvecs @ w, w)).as_matrix()
    a, misses = circle_centre(w, turns, tracks, w @ sample.mean(axis=0))
    return w, a, misses, turns


def rotation_variance(rotations: np.ndarray, sample: np.ndarray, part_noise_m: float) -> float:
    """Variance of one component of (R_k - I) w at the true w: the rotations' own misfit (2K - 2 degrees of
    freedom), at least what `part_noise_m` on the model points gives over their RMS distance from their centroid
    (a rigid registration's turn error)."""
    lever = float(np.sqrt(np.mean(np.sum((sample - sample.mean(axis=0)) ** 2, axis=1))))
    floor = (part_noise_m / max(lever, part_noise_m)) ** 2
    if len(rotations) < 2:
        return floor
    m = rotations - np.eye(3)
    misfit = float(np.linalg.eigvalsh(np.einsum("kji,kjl->il", m, m))[0]) / (2 * len(rotations) - 2)
    return max(misfit, floor)


def hinge_information(rotations: np.ndarray, rotation_var: float, path: Track | None) -> np.ndarray:
    """The (3,3) matrix whose quadratic form in a unit w is the noise-weighted misfit of w: sum |(R_k - I) w|^2
    over `rotation_var`, plus with the gripper's `path` sum ((p_n - mean) . w)^2 over its variance (its own
    out-of-plane misfit, N - 3 degrees of freedom, at least its noise squared)."""
    m = rotations - np.eye(3)
    information = np.einsum("kji,kjl->il", m, m) / rotation_var
    if path is not None:
        positions, noise_m = path
        centred = np.asarray(positions, float) - np.mean(positions, axis=0)
        scatter = centred.T @ centred
        dof = len(centred) - 3
        variance = max(float(np.linalg.eigvalsh(scatter)[0]) / dof if dof > 0 else 0.0, noise_m**2)
        information = information + scatter / variance
    return information


def _information_sigma_deg(information: np.ndarray, w: np.ndarray, plate: np.ndarray | None = None) -> float:
    """RMS angle error (deg) of the w that minimises the quadratic form `information`: over the rise of the form
    as w tips toward each of the two other directions (its other eigenvalues less w's own); for a w kept in a plate
    (normal `plate`), toward the one direction within it."""
    own = float(w @ information @ w)
    if plate is not None:
        u = np.cross(w, plate)
        u = u / np.linalg.norm(u)
        return float(np.degrees(1 / np.sqrt(max(float(u @ information @ u) - own, 1e-18))))
    rise = np.maximum(np.linalg.eigvalsh(information)[1:] - own, 1e-18)
    return float(np.degrees(np.sqrt(np.sum(1 / rise))))


def hinge_scatter_deg(rotations: np.ndarray, w: np.ndarray, plate: np.ndarray | None = None) -> float | None:
    """RMS angle error (deg) of the hinge direction `w` from the rotations' misfit: the residual variance of
    R_k w = w (each rotation pins w by two equations: 2K - 2 degrees of freedom) over the information across
    w (the two other eigenvalues of N = sum (R_k - I)^T (R_k - I)). For a w projected into a plate (normal
    `plate`) only its turn within the plate counts: the misfit along the plate's normal (what a tilt of w
    within the plate leaves; K - 1 degrees of freedom) over u^T N u, u = w x plate (registration's error
    about the plate's normal, its worst, shows across w within the plate and is projected away). None from
    one rotation, whose own axis fits it exactly whatever its error."""
    if len(rotations) < 2:
        return None
    m = rotations - np.eye(3)
    normal = np.einsum("kji,kjl->il", m, m)
    if plate is not None:
        u = np.cross(w, plate)
        misfit = float(np.sum((m @ w @ plate) ** 2)) / (len(rotations) - 1)
        return float(np.degrees(np.sqrt(misfit / max(u @ normal @ u / (u @ u), 1e-18))))
    residual = max(float(w @ normal @ w), 0.0)
    across = np.linalg.eigvalsh(normal - residual * np.outer(w, w))[1:]
    return float(np.degrees(np.sqrt(residual / (2 * len(rotations) - 2) * np.sum(1 / np.maximum(across, 1e-18)))))


def hinge_direction(
    rotations: np.ndarray, plate: np.ndarray | None, rotation_var: float = 1.0, path: Track | None = None
) -> np.ndarray:
    """The unit w that minimises `hinge_information` (least squares over R_k w = w, and with the gripper's
    `path` over its plane), in the plate with normal `plate` (a door panel) when within 30 deg of it: without
    a path projected into it, with one the least squares within it."""
    information = hinge_information(rotations, rotation_var, path)
    w = np.linalg.eigh(information)[1][:, 0]
    if plate is None or abs(w @ plate) >= np.sin(np.radians(_MAX_HINGE_TILT_DEG)):
        return w
    if path is None:
        w = w - (w @ plate) * plate
        return w / np.linalg.norm(w)
    basis = np.column_stack(plane_basis(plate))
    return basis @ np.linalg.eigh(basis.T @ information @ basis)[1][:, 0]


def bic(rms_m: float, n: int, k: int, noise_floor_m: float) -> float:
    """Bayesian information criterion of a fit with RMS residual `rms_m` over n measurements and k
    parameters; residuals below `noise_floor_m` count as noise."""
    return float(n * np.log(rms_m**2 + noise_floor_m**2) + k * np.log(n))


def grip_bic(path: np.ndarray | None, fit: JointFit, joint: JointType, noise_m: float) -> float:
    """The gripper path's share of the BIC of a joint fit: 3 N ln(miss^2 + noise_m^2) over its N positions, the
    miss its RMS distance from the fit's line (`line_miss`) or from the circle about the fit's axis
    (`circle_miss`); 0 without a path."""
    if path is None or len(path) < 3:
        return 0.0
    miss = line_miss(path, fit.direction) if joint is JointType.PRISMATIC else circle_miss(path, fit.direction)
    return float(3 * len(path) * np.log(miss**2 + noise_m**2))


def circle_miss(positions: np.ndarray, direction: np.ndarray) -> float:
    """RMS distance (m) of positions from the circle about an axis along `direction` (unit) that fits
    them best (centre and radius free: an algebraic circle fit in the plane normal to it, then the spread of the
    distances from its centre and of the heights along the axis)."""
    offsets = np.asarray(positions, float) - np.mean(positions, axis=0)
    u, v = plane_basis(direction)
    x, y = offsets @ u, offsets @ v
    design = np.column_stack([x, y, np.ones_like(x)])
    cx, cy, c = np.linalg.lstsq(design, x**2 + y**2, rcond=None)[0]
    radius = np.hypot(x - cx / 2, y - cy / 2)
    return float(np.sqrt(np.var(radius) + np.var(offsets @ direction)))


def circle_centre(
    w: np.ndarray, turns: np.ndarray, tracks: list[Track], anchor: float
) -> tuple[np.ndarray, list[float]]:
    """The point a of the axis (direction w, a @ w = anchor) about which each track of positions
    p_0..p_K (start, then after each of the K `turns`) moves: p_k = a + R_k v, one lever v per track,
    every track weighted by 1 / its noise (m). Returns a and each track's RMS residual (m)."""
    rotations = np.concatenate([np.eye(3)[None], turns])
    cols = 3 + 3 * len(tracks)
    rows, rhs = [], []
    for j, (positions, sigma) in enumerate(tracks):
        block = np.zeros((len(rotations), 3, cols))
        block[:, :, :3] = np.eye(3)
        block[:, :, 3 + 3 * j: 6 + 3 * j] = rotations
        rows.append(block.reshape(-1, cols) / sigma)
        rhs.append(np.asarray(positions).ravel() / sigma)
    rows.append(np.append(w, np.zeros(cols - 3))[None] * 1e3)  # a @ w = anchor: the tracks leave a free along w
    rhs.append([anchor * 1e3])
    x = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    a = x[:3]
    rms = [
        float(np.sqrt(np.mean(np.sum((positions - a - rotations @ x[3 + 3 * j: 6 + 3 * j]) ** 2, axis=1))))
        for j, (positions, _) in enumerate(tracks)
    ]
    return a, rms


def principal_direction(tracks: list[Track]) -> np.ndarray:
    """The unit direction along which the tracks' positions spread most (each about its own mean,
    weighted by 1 / its noise)."""
    centred = np.vstack([(positions - positions.mean(axis=0)) / sigma for positions, sigma in tracks])
    return np.linalg.svd(centred, full_matrices=False)[2][0]


def line_miss(positions: np.ndarray, direction: np.ndarray) -> float:
    """RMS distance (m) of positions from the line through their mean along `direction`."""
    offsets = positions - positions.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum((offsets - np.outer(offsets @ direction, direction)) ** 2, axis=1))))


def distance_to_line(point: np.ndarray, fit: JointFit) -> float:
    """Distance (m) from `point` to the fitted joint's line."""
    offset = point - fit.point
    return float(np.linalg.norm(offset - (offset @ fit.direction) * fit.direction))


def plate_normal(points: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Normal of the plate the points mostly lie on (`_trimmed_plane`) and its standard error (deg, as
    `front_face`'s), None when they are not a plate: less than 60 % of them within 3 median distances (at
    least 2 mm) of the plane, or a thickness spread over 10 % of the width spread."""
    normal, spread, kept = _trimmed_plane(points)
    if kept < 0.6 * len(points) or spread[2] > 0.1 * spread[1]:
        return None
    samples = max(kept / _FRONT_POINTS_PER_SAMPLE, 1.0)
    return normal, float(np.degrees(spread[2] / max(spread[1], 1e-12) / np.sqrt(samples)))
