"""The paper's radius outlier filter: keep p iff at least `eps` other points lie within `radius_m` of it.

Rule: keep p iff |{q in P, q != p : |p - q| <= r}| >= eps (boundary inclusive; duplicates count as other
points). This is Open3D's `remove_radius_outlier(nb_points=eps, radius=r)`, whose search also returns p
itself and keeps when it finds more than nb_points; Open3D's search is strict (< r), so the two differ
only for pairs at exactly distance r.

Fast path (exact: it changes no result, only skips work). Points are binned in voxel grids and each
point gets a lower and an upper bound on its neighbour count; only points whose bounds straddle eps are
counted exactly (scipy cKDTree, built on the points within reach of them).
- Coarse grid, side r / sqrt(3): two points of one cell are within r, so a cell holding >= eps + 1
  points keeps all of them; every point within r of p lies in the 5x5x5 block around p's cell, so a
  block holding <= eps points drops p.
- Fine grid, side r / (2 sqrt(3)), for the points still undecided: the 3x3x3 block around p's cell lies
  wholly within r of p (lower bound), and the cells whose nearest point is within r of p's cell (a
  rounded 9x9x9 block) hold every neighbour (upper bound).
On dense surface clouds almost every point is decided by the grids.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np
from scipy.spatial import cKDTree

_UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_MAX_KEY = 2.0**62
_COARSE_REACH = np.array(list(product(range(-2, 3), repeat=3)), dtype=np.int64)
_FINE_WITHIN = np.array(list(product(range(-1, 2), repeat=3)), dtype=np.int64)
_FINE_REACH = np.array(
    [d for d in product(range(-4, 5), repeat=3) if sum(max(abs(x) - 1, 0) ** 2 for x in d) <= 12],
    dtype=np.int64,
)  # cells at least partly within 2*sqrt(3) fine sides (= r) of the centre cell


def _check(radius: float, eps: int) -> None:
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius filter: radius must be a positive number of metres, got {radius!r}")
    if int(eps) != eps or eps < 1:
        raise ValueError(
            f"radius filter: eps (neighbours required) must be an integer >= 1, got {eps!r}; "
            "eps = 0 would keep every point: skip the filter instead"
        )


@dataclass(frozen=True)
class FilterProfile:
    """A radius-filter setting with an explicit unit for the radius ("m", "cm" or "mm")."""

    radius: float
    eps: int
    unit: str

    def __post_init__(self) -> None:
        if self.unit not in _UNITS_TO_M:
            raise ValueError(
                f"radius filter profile: unknown unit {self.unit!r}; use one of {sorted(_UNITS_TO_M)}"
            )
        _check(self.radius, self.eps)

    @property
    def radius_m(self) -> float:
        return self.radius * _UNITS_TO_M[self.unit]


FILTER_PROFILES: dict[str, FilterProfile] = {
    "sim": FilterProfile(0.05, 100, "m"),
    "sparse": FilterProfile(1.3, 1, "cm"),
}
"""Named settings. "sim" is the paper's simulation setting. "sparse" is its real-camera setting "r = 1.3,
eps = 1", given without a unit: we read centimetres (13 mm). In millimetres the radius would sit at the
D415's point spacing at 0.8 m (about 1.3 mm at 640x480, fx ~ 600 px) plus ~1.5 mm axial noise, so eps = 1
would strip real surface; in metres it would cover the whole object and remove nothing."""


def radius_outlier_mask(points: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    """(N,) bool: True where a point has at least `eps` other points within `radius_m` (inclusive).

    Points with non-finite coordinates are dropped (and not counted as neighbours).
    """
    _check(radius_m, eps)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    keep = np.zeros(len(points), dtype=bool)
    finite = np.flatnonzero(np.all(np.isfinite(points), axis=1))
    if len(finite) > eps:  # otherwise nobody can have eps other points
        keep[finite] = _mask_finite(points[finite], radius_m, int(eps))
    return keep


def radius_filter(points: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    """The points (M,3) kept by `radius_outlier_mask`."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points[radius_outlier_mask(points, radius_m, eps)]


def _mask_finite(points: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    side = radius_m / np.sqrt(3.0) * (1.0 - 1e-9)  # a hair small so rounding cannot break the bounds
    origin = points.min(axis=0)
    coarse = _Grid.build(points, origin, side, pad=2)
    if coarse is None:  # absurd extent for the radius: count every point exactly
        return _exact_counts(points, np.arange(len(points)), radius_m) >= eps
    full = coarse.counts >= eps + 1
    sparse = np.flatnonzero(~full)
    is_open = np.zeros(len(coarse.keys), dtype=bool)
    is_open[sparse[coarse.block_sums(sparse, _COARSE_REACH) > eps]] = True
    keep = full[coarse.inverse]
    if is_open.any():  # every neighbour of an undecided point is in the coarse cells around it
        near = np.flatnonzero(coarse.near(np.flatnonzero(is_open), _COARSE_REACH)[coarse.inverse])
        undecided = np.flatnonzero(is_open[coarse.inverse[near]])
        keep[near[undecided]] = _decide(points[near], undecided, origin, side / 2, radius_m, eps)
    return keep


def _decide(points: np.ndarray, undecided: np.ndarray, origin: np.ndarray, side: float, radius_m: float,
            eps: int) -> np.ndarray:
    """Keep decisions for points[undecided]: fine-grid bounds, exact counts where they straddle eps."""
    fine = _Grid.build(points, origin, side, pad=4)
    if fine is None:
        return _exact_counts(points, undecided, radius_m) >= eps
    cells, at = np.unique(fine.inverse[undecided], return_inverse=True)
    keep = fine.block_sums(cells, _FINE_WITHIN)[at] - 1 >= eps  # minus the point itself
    exact = ~keep & (fine.block_sums(cells, _FINE_REACH)[at] - 1 >= eps)
    if exact.any():
        todo = undecided[exact]
        candidates = np.flatnonzero(fine.near(np.unique(fine.inverse[todo]), _FINE_REACH)[fine.inverse])
        keep[exact] = _exact_counts(points[candidates], np.searchsorted(candidates, todo), radius_m) >= eps
    return keep


def _exact_counts(points: np.ndarray, which: np.ndarray, radius_m: float) -> np.ndarray:
    """Other points within radius_m of points[which]."""
    return cKDTree(points).query_ball_point(points[which], radius_m, return_length=True) - 1


@dataclass(frozen=True)
class _Grid:
    """Occupied voxels as sorted integer keys: `inverse` maps points to cells, `counts` points per cell."""

    keys: np.ndarray
    inverse: np.ndarray
    counts: np.ndarray
    strides: np.ndarray

    @classmethod
    def build(cls, points: np.ndarray, origin: np.ndarray, side: float, pad: int) -> _Grid | None:
        cells = np.floor((points - origin) / side)
        dims = cells.max(axis=0) + 2 * pad + 1
        if np.prod(dims) >= _MAX_KEY:
            return None
        strides = np.array([dims[1] * dims[2], dims[2], 1], dtype=np.int64)
        keys, inverse, counts = np.unique(
            (cells.astype(np.int64) + pad) @ strides, return_inverse=True, return_counts=True
        )
        return cls(keys, inverse.ravel(), counts, strides)

    def block_sums(self, cells: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Points in the cells at `offsets` around each of `cells` (indices into keys)."""
        total = np.zeros(len(cells), dtype=np.int64)
        for offset in offsets @ self.strides:
            found = self._lookup(self.keys[cells] + offset)
            total[found >= 0] += self.counts[found[found >= 0]]
        return total

    def near(self, cells: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """(n_cells,) bool: cells at `offsets` around any of `cells`."""
        marked = np.zeros(len(self.keys), dtype=bool)
        for offset in offsets @ self.strides:
            found = self._lookup(self.keys[cells] + offset)
            marked[found[found >= 0]] = True
        return marked

    def _lookup(self, wanted: np.ndarray) -> np.ndarray:
        """Index of each wanted key in the sorted keys, -1 where absent."""
        idx = np.minimum(np.searchsorted(self.keys, wanted), len(self.keys) - 1)
        return np.where(self.keys[idx] == wanted, idx, -1)
