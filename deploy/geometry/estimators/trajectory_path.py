"""A recorded handle path made fit for model selection: its noise level, glitches removed, pauses and
uneven sampling evened out, and the statistics that compare fits on it.

Pure numpy functions; metres, radians inside, degrees where a name says so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.trajectory_fit import plane_basis

_CHI3_MEDIAN = 1.5382  # median of the chi distribution with 3 degrees of freedom
_SG5_RESIDUAL = np.array([3.0, -12.0, 18.0, -12.0, 3.0]) / 35  # sample minus its 5-point quadratic fit
_GLITCH_WINDOW = 7
_MIN_GLITCH_M = 0.01
_CELLS_ALONG_PATH = 100
_MIN_SIGMA_DEG = 0.01


@dataclass(frozen=True)
class PreparedPath:
    """The samples as the fits see them.

    cells (M,3): median position of the samples in each occupied cell of a grid of `cell_m`, ordered by
    the mean time rank of their samples (pauses and dense sampling count once per cell, not per
    sample); rotvecs (M,3): each cell's mean orientation relative to the start orientation that all
    cells agree on (`from_mean_start`; rotation vectors, base frame), None without orientations;
    kept (N,): samples that are not glitches;
    noise_m: white noise per axis estimated from the samples themselves (0 for noise-free data);
    travel_m: extent of the kept samples along their principal direction; largest_gap_m: the largest
    distance between cells consecutive in time (a stretch of the path without samples).
    """

    cells: np.ndarray
    rotvecs: np.ndarray | None
    kept: np.ndarray
    noise_m: float
    travel_m: float
    cell_m: float
    largest_gap_m: float


def white_noise_m(positions: np.ndarray) -> float:
    """Per-axis noise (m) of time-ordered samples: the robust scale of each sample's distance from the
    quadratic through it and its 4 neighbours in time (smooth motion, however uneven, cancels)."""
    if len(positions) < 5:
        return 0.0
    windows = np.lib.stride_tricks.sliding_window_view(positions, 5, axis=0)  # (N-4, 3, 5)
    residuals = np.linalg.norm(windows @ _SG5_RESIDUAL, axis=1)
    return float(np.median(residuals) / (_CHI3_MEDIAN * np.linalg.norm(_SG5_RESIDUAL)))


def glitch_mask(positions: np.ndarray, noise_m: float) -> np.ndarray:
    """True for the samples to keep: a sample farther than max(8 noise, 1 cm) from the per-axis median of
    the 7 samples around it in time is a tracking glitch."""
    n = len(positions)
    if n < _GLITCH_WINDOW:
        return np.ones(n, bool)
    half = _GLITCH_WINDOW // 2
    padded = np.concatenate([np.repeat(positions[:1], half, 0), positions, np.repeat(positions[-1:], half, 0)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, _GLITCH_WINDOW, axis=0)
    deviation = np.linalg.norm(positions - np.median(windows, axis=2), axis=1)
    kept = deviation <= max(8 * noise_m, _MIN_GLITCH_M)
    return kept if kept.sum() >= 3 else np.ones(n, bool)


def relative_rotvecs(quaternions: np.ndarray) -> np.ndarray:
    """Each orientation relative to the first, as a rotation vector in the base frame (N,3)."""
    rotations = Rotation.from_quat(quaternions)
    return (rotations * rotations[0].inv()).as_rotvec()


def rotation_axis(rotvecs: np.ndarray) -> np.ndarray:
    """The common axis w (unit, sign arbitrary) of rotations R_k (rotation vectors (N,3)) that turn one
    orientation about it: R_k = Rot(theta_k, w) S, so w = R_k u with u fixed in the turning body; least
    squares over w and u gives w as the leading left singular vector of the sum of the R_k. The same for
    any common reference S: no single reading's noise leans the axis (a reference sample's 0.5 deg over a
    40 deg turn leaned the fixed-point R_k w = w by about 1.5 deg)."""
    return np.linalg.svd(Rotation.from_rotvec(rotvecs).as_matrix().sum(axis=0))[0][:, 0]


def from_mean_start(rotvecs: np.ndarray, rounds: int = 2) -> np.ndarray:
    """Rotations (N,3) relative to one sample, re-expressed relative to the start orientation that all of
    them agree on: each turned back by its own angle about their common axis (`rotation_axis`), then
    averaged (chordal mean). Angles then count from that start, not from one sample's noisy reading."""
    rotations = Rotation.from_rotvec(rotvecs)
    w = rotation_axis(rotvecs)
    for _ in range(rounds):
        angles = rotations.as_rotvec() @ w
        start = (Rotation.from_rotvec(-np.outer(angles, w)) * rotations).mean()
        rotations = rotations * start.inv()
    return rotations.as_rotvec()


def prepare_path(positions: np.ndarray, quaternions: np.ndarray | None = None) -> PreparedPath:
    """Noise level, glitches and cells (`PreparedPath`) of time-ordered positions (N,3) and orientations
    (N,4, xyzw) or None. Cells are max(3 noise, travel / 100) wide: noise-free samples keep a cell each."""
    noise_m = white_noise_m(positions)
    kept = glitch_mask(positions, noise_m)
    points = positions[kept]
    centred = points - points.mean(axis=0)
    travel_m = float(np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2][0]))
    cell_m = max(3 * noise_m, travel_m / _CELLS_ALONG_PATH, 1e-6)
    keys = np.floor(points / cell_m).astype(np.int64)
    _, cell_of, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cell_of = cell_of.ravel()
    rank = np.bincount(cell_of, weights=np.arange(len(points), dtype=float)) / counts
    order = np.argsort(rank, kind="stable")
    cells = np.array([np.median(points[cell_of == c], axis=0) for c in order])
    rotvecs = None
    if quaternions is not None:
        relative = relative_rotvecs(quaternions[kept])
        rotvecs = from_mean_start(np.array([relative[cell_of == c].mean(axis=0) for c in order]))
    gap = float(np.max(np.linalg.norm(np.diff(cells, axis=0), axis=1))) if len(cells) > 1 else 0.0
    return PreparedPath(cells, rotvecs, kept, noise_m, travel_m, cell_m, gap)


def effective_fraction(residuals: np.ndarray) -> float:
    """n_eff / n of a sequence of residual vectors (n,k): 1 / the integrated autocorrelation time, summed
    up to the first lag whose autocorrelation is not positive. Correlated misfit (a wobble, tremor
    sampled densely, a pause) counts as fewer independent samples than white noise."""
    r = residuals - residuals.mean(axis=0)
    total = float(np.sum(r * r))
    n = len(r)
    if n < 6 or total <= 0:
        return 1.0
    tau = 1.0
    for lag in range(1, n // 3):
        rho = float(np.sum(r[:-lag] * r[lag:])) / total
        if rho <= 0:
            break
        tau += 2 * rho
    return 1.0 / tau


def blocks(n: int, count: int = 5) -> list[np.ndarray]:
    """Index arrays of up to `count` contiguous blocks of range(n) (at least 3 items each)."""
    count = min(count, n // 3)
    return [] if count < 2 else np.array_split(np.arange(n), count)


def jackknife_sigma_deg(direction: np.ndarray, refit: Callable[[np.ndarray], np.ndarray | None], n: int) -> float:
    """Block-jackknife standard deviation (deg) of a fitted unit `direction`: `refit(keep)` gives the
    direction from the items `keep` (a boolean mask of n) or None; each block of contiguous items is
    left out once. Contiguous blocks keep correlated errors (wobble, drift) in the estimate."""
    replicates = []
    for block in blocks(n):
        keep = np.ones(n, bool)
        keep[block] = False
        d = refit(keep)
        if d is not None:
            replicates.append(d if d @ direction >= 0 else -d)
    if len(replicates) < 2:
        return float("nan")
    r = np.array(replicates)
    spread = np.sum((r - r.mean(axis=0)) ** 2) * (len(r) - 1) / len(r)
    return max(float(np.degrees(np.sqrt(spread))), _MIN_SIGMA_DEG)


def bend_coverage(along: np.ndarray) -> float:
    """How well samples at distances `along` a line would show a bend: the mean squared bow of an arc (a
    parabola in the distance) less its best line over them, relative to the same over evenly spread
    samples of the same extent (1: as good as an unbroken path; two short clusters at the ends of the
    travel: near 0, since a line through them fits any arc)."""

    def bow_misfit(s: np.ndarray) -> float:
        design = np.column_stack([np.ones_like(s), s])
        return float(np.mean((s**2 - design @ np.linalg.lstsq(design, s**2, rcond=None)[0]) ** 2))

    even = bow_misfit(np.linspace(along.min(), along.max(), 101))
    return bow_misfit(along) / even if even > 0 else 0.0


def plane_tilt_deg(points: np.ndarray, normal: np.ndarray) -> float:
    """The standard error (deg) of the tilt of a plane with unit `normal` through time-ordered `points`
    about their shorter in-plane spread (an arc's sagitta, not its chord): the points' RMS height off the
    plane over that spread net of the same noise, and over the square root of their effective number
    (`effective_fraction`: a part's play that bends the path along the hinge counts as few samples).
    Infinite when the noise accounts for all of that spread (a near-straight arc: any plane through the
    chord fits)."""
    centred = points - points.mean(axis=0)
    heights = centred @ normal
    in_plane = centred @ np.column_stack(plane_basis(normal))
    height_var = float(np.mean(heights**2))
    lever_var = float(np.linalg.eigvalsh(in_plane.T @ in_plane / len(points))[0]) - height_var
    if lever_var <= 0:
        return float("inf")
    n_eff = max(len(points) * effective_fraction(heights[:, None]), 1.0)
    return float(np.degrees(np.sqrt(height_var / lever_var / n_eff)))


def turn_play_deg(off_axis_deg: float, angles: np.ndarray) -> float:
    """How far (deg) a turn's axis may lean from its scatter about other axes (`off_axis_deg` per axis)
    when that scatter follows the travel (the part's play, a grasp that rocks): the scatter over the RMS
    of the turn's `angles` (rad) from the start, as if it were all one slow tilt, which the block jackknife's
    sigma barely sees (its coverage with and without this term: docs/benchmarks.md)."""
    spread = float(np.sqrt(np.mean(angles**2)))
    return float(np.degrees(np.radians(off_axis_deg) / spread)) if spread > 0 else float("inf")
