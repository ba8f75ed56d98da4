"""The paper's radius outlier filter: keep p iff at least `eps` other points lie within `radius_m` of it.

Rule: keep p iff |{q in P, q != p : |p - q| <= r}| >= eps (boundary inclusive; duplicates count as other
points). This is Open3D's `remove_radius_outlier(nb_points=eps, radius=r)`, whose search also returns p
itself and keeps when it finds more than nb_points; Open3D's search is strict (< r), so the two differ
only for pairs at exactly distance r.

Fast path (exact: it changes no result, only skips work). Each point gets a lower and an upper bound on
its neighbour count from voxel-grid counts; only points whose bounds straddle eps are counted exactly
(scipy cKDTree, built on the points within reach of them). A grid stores a prefix sum over all its cells
when its box is small (dense), else its points' sorted cell keys, and every block of cells is a set of
x-rows, so a block costs two lookups per row (an array read, or a binary search when sparse).
1. Coarse grid, side r / sqrt(3): two points of one cell are within r, so a cell holding >= eps + 1
   points keeps all of them. If the other points share cells (two or more per cell on average), the
   5x5x5 block around a cell, which holds every neighbour of its points, drops them if it holds <= eps.
2. Fine grid, side r / (2 sqrt(3)), over the box that holds every neighbour of the points still
   undecided, if it can be dense: the rounded block of cells wholly within r of every point of a cell
   bounds its points' counts from below, the rounded block of cells that come within r of it from above.
3. Per point, on the finer grid available: the cells wholly inside the point's own r-ball and the cells
   that touch it, found row by row (tighter than per cell). Points whose upper bound is already small
   skip this: their exact count is cheaper.
4. Exact counts for the rest, with a tree on the points in their upper blocks.
On dense surface clouds almost every point is decided by steps 1 and 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product
from math import isqrt

import numpy as np

_UNITS_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_HAIR = 1e-6  # relative slack on every bound, far above float rounding of cell coordinates
_MAX_AXIS_CELLS = 2**20  # keeps cell coordinates exact to ~1e-9 cells and keys within int64
_DENSE_CELLS = (2**18, 16)  # a grid is dense up to max(2^18, 16 per point) cells
_CHUNK = 2**14  # (row, point) pairs per vectorised step: temporaries stay small
_ROW_COST = 5  # step 3 costs about as much as checking 5 neighbours per row of the upper block exactly


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
    """A radius-filter setting: `radius` in the explicit `unit` ("m", "cm" or "mm"; `radius_m` in metres),
    so that a setting is written as its source gives it (the paper's 1.3 cm) and never depends on context."""

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

    def __str__(self) -> str:
        given = "" if self.unit == "m" else f" ({self.radius:g} {self.unit})"
        return f"radius {self.radius_m:g} m{given}, eps {self.eps}"


FILTER_PROFILES: dict[str, FilterProfile] = {
    "sim": FilterProfile(0.05, 100, "m"),
    "sparse": FilterProfile(1.3, 1, "cm"),
}
"""Named settings, each with its unit. "sim" is the paper's simulation setting (r = 0.05 m, eps = 100). "sparse"
is its real-camera setting (D415) "r = 1.3, eps = 1", given there without a unit: we read centimetres (13 mm,
`radius_m` 0.013; a run config overrides it in metres only, `[filter] radius_m`). In millimetres the radius
would sit at the D415's point spacing at 0.8 m (about 1.3 mm at 640x480, fx ~ 600 px) plus ~1.5 mm axial
noise, so eps = 1 would strip real surface; in metres it would cover the whole object and remove nothing."""


def radius_outlier_mask(points: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    """(N,) bool: True where a point has at least `eps` other points within `radius_m` (inclusive).

    Points with non-finite coordinates are dropped (and not counted as neighbours).
    """
    _check(radius_m, eps)
    xyz = np.array(np.asarray(points, dtype=np.float64).reshape(-1, 3).T, order="C")  # (3, N)
    keep = np.zeros(xyz.shape[1], dtype=bool)
    finite = np.isfinite(xyz)
    finite = finite[0] & finite[1] & finite[2]
    if finite.all():
        return _mask_finite(xyz, radius_m, int(eps)) if len(keep) > eps else keep
    finite = np.flatnonzero(finite)
    if len(finite) > eps:  # otherwise nobody can have eps other points
        keep[finite] = _mask_finite(np.take(xyz, finite, axis=1), radius_m, int(eps))
    return keep


def radius_filter(points: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    """The points (M,3) kept by `radius_outlier_mask`."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points[radius_outlier_mask(points, radius_m, eps)]


def _mask_finite(xyz: np.ndarray, radius_m: float, eps: int) -> np.ndarray:
    """Keep decisions for the (3, n) finite points xyz, by the steps of the module docstring."""
    coarse = _Grid.build(xyz, xyz.min(axis=1), xyz.max(axis=1), radius_m, 1)
    if coarse is None:  # absurd extent for the radius: count every point exactly
        return _exact_counts(xyz, np.arange(xyz.shape[1]), radius_m) >= eps
    keep = coarse.own_counts() - 1 >= eps
    todo = np.flatnonzero(~keep)  # undecided points
    upper = None  # their upper bounds, once known
    cells, inverse = _unique(coarse.keys[todo])
    if 2 * len(cells) <= len(todo):
        upper = coarse.block_counts(cells, coarse.blocks.upper)[inverse] - 1
        todo, upper = todo[upper >= eps], upper[upper >= eps]
    if len(todo) == 0:
        return keep
    grid, points, at = coarse, xyz, todo  # the finest grid, its points and todo's indices among them
    fine = _fine_grid(xyz, todo, radius_m)
    if fine is not None:
        grid, points, inside = fine
        at = np.searchsorted(inside, todo)
        lower = _block_others(grid, at, grid.blocks.lower)
        keep[todo[lower >= eps]] = True
        todo, at = todo[lower < eps], at[lower < eps]
        upper = _block_others(grid, at, grid.blocks.upper)
        todo, at, upper = todo[upper >= eps], at[upper >= eps], upper[upper >= eps]
        if len(todo) == 0:
            return keep
    kept, exact, (start, stop) = _point_bounds(grid, points, at, upper, radius_m, eps)
    keep[todo[kept]] = True
    if len(exact):
        near = np.flatnonzero(grid.mark(start, stop))
        counts = _exact_counts(np.take(points, near, axis=1), np.searchsorted(near, at[exact]), radius_m)
        keep[todo[exact]] = counts >= eps
    return keep


def _fine_grid(xyz: np.ndarray, todo: np.ndarray,
               radius_m: float) -> tuple[_Grid, np.ndarray, np.ndarray] | None:
    """Step 2's grid over the box holding every neighbour of the points todo, if it can be dense; with the
    (3, m) points inside the box and their indices."""
    undecided = np.take(xyz, todo, axis=1)
    lo = undecided.min(axis=1) - 1.001 * radius_m
    hi = undecided.max(axis=1) + 1.001 * radius_m
    box = (xyz >= lo[:, None]) & (xyz <= hi[:, None])
    inside = np.flatnonzero(box[0] & box[1] & box[2])
    points = np.take(xyz, inside, axis=1)
    grid = _Grid.build(points, lo, hi, radius_m, 2, dense_only=True)
    return None if grid is None else (grid, points, inside)


def _point_bounds(grid: _Grid, points: np.ndarray, at: np.ndarray, upper: np.ndarray | None, radius_m: float,
                  eps: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Step 3 for the grid's points `at`, whose upper bounds are `upper` (None: unknown): the indices into
    `at` kept and left to count exactly, and the rank ranges of the cells within reach of the latter."""
    costly = np.ones(len(at), dtype=bool) if upper is None else upper > _ROW_COST * len(grid.blocks.upper)
    bounded = np.flatnonzero(costly)
    bounded = bounded[np.argsort(grid.keys[at[bounded]], kind="stable")]  # key order: cache-friendly lookups
    lower, _, _ = grid.ball_counts(points, at[bounded], radius_m, inner=True)
    kept, bounded = bounded[lower - 1 >= eps], bounded[lower - 1 < eps]
    upper, start, stop = grid.ball_counts(points, at[bounded], radius_m, inner=False)
    straddle = upper - 1 >= eps
    cheap_start, cheap_stop = grid.row_ranks(np.unique(grid.keys[at[~costly]]), grid.blocks.upper)
    ranges = (np.concatenate([start[:, straddle].ravel(), cheap_start.ravel()]),
              np.concatenate([stop[:, straddle].ravel(), cheap_stop.ravel()]))
    return kept, np.concatenate([bounded[straddle], np.flatnonzero(~costly)]), ranges


def _block_others(grid: _Grid, at: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Other points in the block `rows` around the cell of each of the grid's points `at`."""
    cells, inverse = _unique(grid.keys[at])
    return grid.block_counts(cells, rows)[inverse] - 1


def _unique(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(keys, return_inverse=True), quicker on keys that come in runs (scan order)."""
    order = np.argsort(keys, kind="stable")
    first = np.empty(len(keys), dtype=bool)
    first[:1] = True
    np.not_equal(keys[order[1:]], keys[order[:-1]], out=first[1:])
    inverse = np.empty(len(keys), dtype=np.int64)
    inverse[order] = np.cumsum(first) - 1
    return keys[order[first]], inverse


def _exact_counts(xyz: np.ndarray, which: np.ndarray, radius_m: float) -> np.ndarray:
    """Other points within radius_m of the (3, n) points xyz[:, which]."""
    from scipy.spatial import cKDTree  # here: the CLI imports this module for its profiles, scipy is slow to load

    points = xyz.T
    tree = cKDTree(points, leafsize=64, balanced_tree=False, compact_nodes=False)  # quick to build
    return tree.query_ball_point(points[which], radius_m, return_length=True) - 1


def _chunks(n: int, n_rows: int) -> list[slice]:
    """Slices of range(n) holding about _CHUNK (row, item) pairs each."""
    step = max(1, _CHUNK // max(n_rows, 1))
    return [slice(i, i + step) for i in range(0, n, step)]


@dataclass(frozen=True)
class _Blocks:
    """The cell blocks of a grid of side r / (k sqrt(3)), as x-rows (dy, dz, half-length) around a cell."""

    k: int
    lower: np.ndarray  # (m, 3) rows of the cells wholly within r of every point of the centre cell
    upper: np.ndarray  # (m, 3) rows of the cells that come within r of the centre cell
    inner: np.ndarray  # (m, 3) rows (half-length unused) that can hold cells wholly inside a point's r-ball
    reach: int  # padding: no block reaches further than this many cells

    @classmethod
    def of(cls, k: int) -> _Blocks:
        n = 3 * k * k  # (r / side)^2 in cells^2; the side is a hair small, so these bounds hold
        reach = isqrt(n) + 1
        lower, upper = [], []
        for dy, dz in product(range(-reach, reach + 1), repeat=2):
            rest = n - (abs(dy) + 1) ** 2 - (abs(dz) + 1) ** 2  # farthest points of the rows
            if rest >= 1:
                lower.append((dy, dz, isqrt(rest) - 1))
            rest = n - max(abs(dy) - 1, 0) ** 2 - max(abs(dz) - 1, 0) ** 2  # nearest points of the rows
            if rest >= 0:
                upper.append((dy, dz, isqrt(rest) + 1))
        inner = [row for row in upper if row[0] ** 2 + row[1] ** 2 < n]
        return cls(k, *(np.array(rows, dtype=np.int64) for rows in (lower, upper, inner)), reach)


_BLOCKS = {1: _Blocks.of(1), 2: _Blocks.of(2)}


@dataclass(frozen=True)
class _Grid:
    """Voxel counts of some points: a cell's key is its flat index, x fastest, so an x-row is a key range."""

    blocks: _Blocks
    origin: np.ndarray  # (3,) corner of the first unpadded cell
    side: float
    stride: np.ndarray  # (3,) key steps along x, y, z
    keys: np.ndarray  # (n,) cell key of each point
    prefix: np.ndarray | None  # dense: prefix[key] = points in cells of smaller key
    order: np.ndarray | None  # sparse: the points sorted by key ...
    sorted_keys: np.ndarray | None  # ... and their keys

    @classmethod
    def build(cls, xyz: np.ndarray, lo: np.ndarray, hi: np.ndarray, radius_m: float, k: int,
              dense_only: bool = False) -> _Grid | None:
        """Grid of side r / (k sqrt(3)) over the box [lo, hi] holding the (3, n) points xyz; None if it
        would be too large (or not dense when `dense_only`)."""
        blocks = _BLOCKS[k]
        side = radius_m / (k * np.sqrt(3.0)) * (1.0 - _HAIR)
        dims = np.floor((hi - lo) / side).astype(np.int64) + 1 + 2 * blocks.reach
        if dims.max() > _MAX_AXIS_CELLS:
            return None
        n_cells = int(np.prod(dims))
        dense = n_cells <= max(_DENSE_CELLS[0], _DENSE_CELLS[1] * xyz.shape[1])
        if dense_only and not dense:
            return None
        stride = np.array([1, dims[0], dims[0] * dims[1]], dtype=np.int64)
        keys = np.full(xyz.shape[1], blocks.reach * stride.sum(), dtype=np.int64)
        for axis in range(3):
            keys += np.floor((xyz[axis] - lo[axis]) / side).astype(np.int64) * stride[axis]
        if dense:
            prefix = np.bincount(keys + 1, minlength=n_cells + 1)
            np.cumsum(prefix, out=prefix)
            return cls(blocks, lo, side, stride, keys, prefix, None, None)
        order = np.argsort(keys, kind="stable")
        return cls(blocks, lo, side, stride, keys, None, order, keys[order])

    def rank(self, keys: np.ndarray) -> np.ndarray:
        """Points in cells of smaller key than each of keys."""
        if self.prefix is not None:
            return self.prefix[keys]
        return np.searchsorted(self.sorted_keys, keys)

    def own_counts(self) -> np.ndarray:
        """(n,) points in each point's cell."""
        if self.prefix is not None:
            return self.prefix[self.keys + 1] - self.prefix[self.keys]
        first = np.empty(len(self.keys), dtype=bool)
        first[0] = True
        np.not_equal(self.sorted_keys[1:], self.sorted_keys[:-1], out=first[1:])
        starts = np.flatnonzero(first)
        counts = np.empty(len(self.keys), dtype=np.int64)
        counts[self.order] = np.diff(np.append(starts, len(first)))[np.cumsum(first) - 1]
        return counts

    def row_ranks(self, cells: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(len(rows), len(cells)) ranks of the first and past-the-last cell of each row around each cell."""
        offset = (rows[:, 0] * self.stride[1] + rows[:, 1] * self.stride[2])[:, None] + cells
        return self.rank(offset - rows[:, 2:]), self.rank(offset + rows[:, 2:] + 1)

    def block_counts(self, cells: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Points in the block `rows` around each of cells (keys)."""
        counts = np.empty(len(cells), dtype=np.int64)
        for part in _chunks(len(cells), len(rows)):
            start, stop = self.row_ranks(cells[part], rows)
            counts[part] = (stop - start).sum(axis=0)
        return counts

    def ball_counts(self, xyz: np.ndarray, which: np.ndarray, radius_m: float,
                    inner: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points in the cells wholly inside (inner) or touching the r-ball around each point xyz[:, which]
        (one of this grid's points), and the (rows, n) rank ranges [start, stop) of those cells by row."""
        rows = self.blocks.inner if inner else self.blocks.upper
        reach2 = (radius_m / self.side) ** 2 * (1 - 4 * _HAIR if inner else 1 + 4 * _HAIR)
        offset = (rows[:, 0] * self.stride[1] + rows[:, 1] * self.stride[2])[:, None]
        dy, dz = rows[:, :1].astype(np.float64), rows[:, 1:2].astype(np.float64)
        frac = [(xyz[axis, which] - self.origin[axis]) / self.side for axis in range(3)]
        fx, fy, fz = (f - np.floor(f) for f in frac)  # position in the cell, as in `build`
        counts = np.empty(len(which), dtype=np.int64)
        start = np.empty((len(rows), len(which)), dtype=np.int64)
        stop = np.empty_like(start)
        for part in _chunks(len(which), len(rows)):
            x, y, z = fx[part], fy[part], fz[part]
            if inner:  # farthest points of each row's cells in y and z
                d2 = np.maximum(dy + 1 - y, y - dy) ** 2 + np.maximum(dz + 1 - z, z - dz) ** 2
            else:  # nearest points
                d2 = np.maximum(np.maximum(dy - y, y - dy - 1), 0) ** 2
                d2 += np.maximum(np.maximum(dz - z, z - dz - 1), 0) ** 2
            half = np.sqrt(np.maximum(reach2 - d2, 0.0))  # half-length of the ball's chord along x
            if inner:  # cells [i, i + 1) inside [x - half, x + half], as offsets [lo, hi) from the point's
                lo = np.ceil(x - half).astype(np.int64)
                hi = np.maximum(np.floor(x + half).astype(np.int64), lo)
            else:  # cells meeting it
                lo = np.floor(x - half).astype(np.int64)
                hi = np.where(d2 <= reach2, np.floor(x + half).astype(np.int64) + 1, lo)
            key = self.keys[which[part]] + offset
            start[:, part], stop[:, part] = self.rank(key + lo), self.rank(key + hi)
            counts[part] = (stop[:, part] - start[:, part]).sum(axis=0)
        return counts, start, stop

    def mark(self, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
        """(n,) bool: points whose rank lies in one of the ranges [start, stop) of whole cells."""
        n = len(self.keys)
        depth = np.bincount(start, minlength=n + 1)
        depth -= np.bincount(stop, minlength=n + 1)
        np.cumsum(depth, out=depth)
        if self.prefix is not None:
            return depth[self.prefix[self.keys]] > 0  # a cell's points share the rank of its first one
        marked = np.empty(n, dtype=bool)
        marked[self.order] = depth[:n] > 0
        return marked
