"""Robust line and 3D circle fits to points: sampling over minimal sets (fixed seed) for the model with the
smallest `coverage` quantile of squared residuals (0.5: least median of squares), then least squares on
the inliers. Pure numpy/scipy; metres."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

_MIN_INLIER_M = 1e-4
_SAMPLES = 300
_SEED = 0


def unit(v: np.ndarray) -> np.ndarray:
    """v scaled to length 1."""
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


def line_residuals(points: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Distance (m) of each point to the line through `origin` along unit `direction`."""
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
    line, _ = fit_line_inliers(_check_points(points, 2, "fit_line"))
    return line


def fit_line_inliers(
    points: np.ndarray, coverage: float = 0.5
) -> tuple[tuple[np.ndarray, np.ndarray, float], np.ndarray]:
    """The line and its inlier mask. The sampled line that best explains the `coverage` share of the
    points seeds it: 0.5 breaks down only at half the points gross outliers, but may then follow a half
    of the path that a part's play bent away from the other half; points cleared of gross outliers
    beforehand can ask for more (e.g. 0.8)."""
    pairs = _sample_sets(len(points), 2)
    starts, chords = points[pairs[:, 0]], points[pairs[:, 1]] - points[pairs[:, 0]]
    lengths = np.linalg.norm(chords, axis=1)
    keep = lengths > 1e-9
    if not keep.any():
        raise ValueError("fit_line: all points coincide, so they define no line")
    starts, directions = starts[keep], chords[keep] / lengths[keep, None]
    d = points[None] - starts[:, None]
    along = np.einsum("mnk,mk->mn", d, directions)
    scores = np.quantile(np.linalg.norm(d - along[..., None] * directions[:, None], axis=2), coverage, axis=1)
    best = starts[np.argmin(scores)], directions[np.argmin(scores)]
    inliers = np.ones(len(points), bool)
    for _ in range(2):
        residuals = line_residuals(points, *best)
        inliers = residuals <= _inlier_threshold(residuals, 4)
        origin = points[inliers].mean(axis=0)
        direction = np.linalg.svd(points[inliers] - origin)[2][0]
        best = (origin, direction)
    residuals = line_residuals(points, *best)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    return (best[0], best[1], rms), inliers


def circle_residuals(
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


def plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors u, v with (u, v, normal) right-handed and orthonormal."""
    u = unit(np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0]))
    return u, np.cross(normal, u)


def _kasa_circle(points: np.ndarray):
    """Initial circle: plane by SVD, then Kasa's algebraic fit in that plane."""
    mean = points.mean(axis=0)
    normal = np.linalg.svd(points - mean)[2][2]
    u, v = plane_basis(normal)
    x, y = (points - mean) @ u, (points - mean) @ v
    (a, b, c), *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x**2 + y**2, rcond=None)
    r2 = c + (a / 2) ** 2 + (b / 2) ** 2
    if r2 <= 0:
        return None
    return mean + a / 2 * u + b / 2 * v, normal, float(np.sqrt(r2))


def refine_circle(points: np.ndarray, center: np.ndarray, normal: np.ndarray, radius: float,
                  max_evaluations: int | None = None):
    """Geometric least squares (analytic Jacobian) over centre, normal (two tilts) and radius, with at
    most `max_evaluations` residual evaluations (None: until converged)."""
    u, v = plane_basis(normal)

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
    solution = least_squares(residuals, x0, jac=jacobian, method="lm", max_nfev=max_evaluations)
    c, m, r = unpack(solution.x)
    return c, unit(m), float(abs(r))


def fit_circle_3d(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Robust 3D circle: (center, unit normal, radius, RMS of the inliers' distances, m).

    Raises ValueError for fewer than 3 points or when the points are collinear (no circle).
    """
    circle, _ = fit_circle_inliers(_check_points(points, 3, "fit_circle_3d"))
    return circle


def fit_circle_inliers(points: np.ndarray, coverage: float = 0.5):
    """The circle and its inlier mask; `coverage` as in `fit_line_inliers`."""
    triples = _sample_sets(len(points), 3)
    centers, normals, radii = _circumcircles(*(points[triples[:, i]] for i in range(3)))
    if len(centers) == 0:
        raise ValueError("fit_circle_3d: the points are collinear, so they define no circle")
    d = points[None] - centers[:, None]
    height = np.einsum("mnk,mk->mn", d, normals)
    in_plane = np.sqrt(np.maximum(np.einsum("mnk,mnk->mn", d, d) - height**2, 0.0))
    m = int(np.argmin(np.quantile(np.hypot(in_plane - radii[:, None], height), coverage, axis=1)))
    best = centers[m], normals[m], float(radii[m])
    residuals = circle_residuals(points, *best)
    inliers = residuals <= _inlier_threshold(residuals, 6)
    if inliers.sum() < 3:
        inliers[:] = True
    candidates = [best] + [c for c in [_kasa_circle(points[inliers])] if c is not None]
    refined = [refine_circle(points[inliers], *c) for c in candidates]
    cost = [np.sum(circle_residuals(points[inliers], *c) ** 2) for c in refined]
    center, normal, radius = refined[int(np.argmin(cost))]
    residuals = circle_residuals(points, center, normal, radius)
    inliers = residuals <= _inlier_threshold(residuals, 6)
    rms = float(np.sqrt(np.mean(residuals[inliers] ** 2)))
    return (center, normal, float(radius), rms), inliers


