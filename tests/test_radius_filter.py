"""The radius filter equals the paper's rule, Open3D's remove_radius_outlier and a brute-force count."""

import numpy as np
import open3d as o3d
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from deploy.geometry import radius_filter as radius_filter_module
from deploy.geometry.radius_filter import FILTER_PROFILES, FilterProfile, radius_filter, radius_outlier_mask


def brute_force(points: np.ndarray, radius: float, eps: int) -> np.ndarray:
    """Other points (by index) within radius, inclusive."""
    dist = cdist(points, points)
    return (dist <= radius).sum(axis=1) - 1 >= eps


def open3d_mask(points: np.ndarray, radius: float, eps: int) -> np.ndarray:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    _, kept = cloud.remove_radius_outlier(nb_points=eps, radius=radius)
    mask = np.zeros(len(points), dtype=bool)
    mask[np.asarray(kept, dtype=int)] = True
    return mask


def clustered_cloud(seed: int, n_clusters: int = 6, n_outliers: int = 200) -> np.ndarray:
    """Gaussian clusters of different densities and a surface patch, plus uniform outliers (metres)."""
    rng = np.random.default_rng(seed)
    parts = [rng.uniform(-0.3, 0.3, (n_outliers, 3))]
    for _ in range(n_clusters):
        size = (rng.integers(20, 400), 3)
        parts.append(rng.normal(rng.uniform(-0.2, 0.2, 3), rng.uniform(0.005, 0.04), size))
    g = np.arange(0.0, 0.1, 0.003)
    plane = np.stack(np.meshgrid(g, g, [0.05]), axis=-1).reshape(-1, 3)
    parts.append(plane + rng.normal(0, 0.0005, plane.shape))
    return np.concatenate(parts)


def test_pair_survives_lone_point_does_not():
    points = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.5, 0.5, 0.5]])
    assert radius_outlier_mask(points, 0.02, 1).tolist() == [True, True, False]
    assert radius_outlier_mask(points, 0.02, 2).tolist() == [False, False, False]
    assert np.array_equal(radius_filter(points, 0.02, 1), points[:2])


def test_open3d_counts_the_point_itself_so_nb_points_equals_eps():
    points = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.5, 0.5, 0.5]])
    assert open3d_mask(points, 0.02, 1).tolist() == [True, True, False]
    assert open3d_mask(points, 0.02, 2).tolist() == [False, False, False]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("radius", "eps"), [(0.02, 1), (0.02, 8), (0.05, 100), (0.01, 3), (0.005, 2)])
def test_equals_open3d_and_brute_force(seed, radius, eps):
    points = clustered_cloud(seed)
    mask = radius_outlier_mask(points, radius, eps)
    assert np.array_equal(mask, brute_force(points, radius, eps))
    assert np.array_equal(mask, open3d_mask(points, radius, eps))
    assert 0 < mask.sum() < len(points)  # the case is not trivial


def test_boundary_is_inclusive_on_an_exact_lattice():
    # 4x4 lattice with spacing exactly r (exact in binary): corners have 2 neighbours, edges 3, inside 4
    r = 0.25
    g = np.arange(4) * r
    points = np.stack(np.meshgrid(g, g, [0.0]), axis=-1).reshape(-1, 3)
    n_neighbours = np.array([2 + (0 < x < 0.75) + (0 < y < 0.75) for x, y, _ in points])
    for eps in (1, 2, 3, 4, 5):
        assert np.array_equal(radius_outlier_mask(points, r, eps), n_neighbours >= eps)


@pytest.mark.parametrize(("scale", "kept"), [(0.995, True), (1.005, False)])
def test_pair_along_a_grid_cell_diagonal(scale, kept):
    # the fast path's cell side is r / sqrt(3): a pair spanning one cell's diagonal is the tightest case
    r = 0.05
    points = np.array([[0.0, 0.0, 0.0], np.full(3, scale * r / np.sqrt(3))])
    assert radius_outlier_mask(points, r, 1).tolist() == [kept, kept]


@settings(max_examples=60, deadline=None)
@given(
    cells=st.lists(st.tuples(*[st.integers(0, 14)] * 3), min_size=0, max_size=400),
    radius_units=st.integers(1, 7),
    eps=st.integers(1, 60),
)
def test_equals_exact_integer_count(cells, radius_units, eps):
    # integer lattice scaled by 2^-8: distances are exact, so ties at exactly r are common
    ijk = np.array(cells, dtype=np.int64).reshape(-1, 3)
    d2 = ((ijk[:, None, :] - ijk[None, :, :]) ** 2).sum(axis=2)
    expected = (d2 <= radius_units**2).sum(axis=1) - 1 >= eps
    mask = radius_outlier_mask(ijk * 2.0**-8, radius_units * 2.0**-8, eps)
    assert np.array_equal(mask, expected)


def test_dense_surface_with_outliers_matches_brute_force():
    rng = np.random.default_rng(7)
    g = np.arange(0.0, 0.06, 0.0015)
    plane = np.stack(np.meshgrid(g, g, [0.0]), axis=-1).reshape(-1, 3)
    points = np.concatenate([plane + rng.normal(0, 0.0003, plane.shape), rng.uniform(-0.05, 0.1, (300, 3))])
    for radius, eps in [(0.01, 100), (0.013, 1), (0.004, 12)]:
        assert np.array_equal(radius_outlier_mask(points, radius, eps), brute_force(points, radius, eps))


def test_huge_extent_falls_back_to_exact_count():
    points = np.array([[0.0, 0.0, 0.0], [0.001, 0.0, 0.0], [1e15, 1e15, 1e15], [1e15, 1e15, 1e15 + 0.5]])
    assert radius_outlier_mask(points, 0.002, 1).tolist() == [True, True, False, False]


def test_non_finite_points_are_dropped_and_not_counted():
    points = np.array([[0, 0, 0], [np.nan, 0, 0], [0.001, 0, 0], [np.inf, 0, 0], [0.5, 0.5, 0.5]])
    assert radius_outlier_mask(points, 0.01, 1).tolist() == [True, False, True, False, False]
    assert radius_outlier_mask(points, 0.01, 2).tolist() == [False] * 5


def test_duplicates_count_as_other_points():
    points = np.array([[0.1, 0.2, 0.3], [0.1, 0.2, 0.3], [0.9, 0.9, 0.9]])
    assert radius_outlier_mask(points, 0.01, 1).tolist() == [True, True, False]


def test_empty_input_gives_empty_output():
    assert radius_outlier_mask(np.zeros((0, 3)), 0.05, 100).shape == (0,)
    assert radius_filter(np.zeros((0, 3)), 0.05, 100).shape == (0, 3)


@pytest.mark.parametrize(
    ("radius", "eps"), [(0.0, 1), (-0.01, 1), (np.nan, 1), (0.01, 0), (0.01, -3), (0.01, 1.5)]
)
def test_bad_parameters_raise(radius, eps):
    with pytest.raises(ValueError, match="radius filter"):
        radius_outlier_mask(np.zeros((3, 3)), radius, eps)


def test_profiles_carry_units():
    assert FilterProfile(1.3, 1, "cm").radius_m == pytest.approx(0.013)
    assert FilterProfile(13, 1, "mm").radius_m == pytest.approx(0.013)
    assert FILTER_PROFILES["sim"].radius_m == pytest.approx(0.05)
    assert FILTER_PROFILES["sim"].eps == 100
    assert FILTER_PROFILES["sparse"].radius_m == pytest.approx(0.013)
    assert FILTER_PROFILES["sparse"].eps == 1
    with pytest.raises(ValueError, match="unknown unit"):
        FilterProfile(1.3, 1, "inch")
    with pytest.raises(ValueError, match="eps"):
        FilterProfile(1.3, 0, "cm")


def scan_cloud(seed: int, step_m: float = 0.0025) -> np.ndarray:
    """Three faces of a 0.2 x 0.15 x 0.25 m box on a jittered grid with depth noise, flying pixels between
    the faces and the camera, and far outliers: the shape of a masked depth-camera object cloud."""
    rng = np.random.default_rng(seed)
    size = np.array([0.2, 0.15, 0.25])
    faces = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        gu, gv = np.meshgrid(np.arange(0, size[u], step_m), np.arange(0, size[v], step_m), indexing="ij")
        face = np.zeros((gu.size, 3))
        face[:, u], face[:, v] = gu.ravel(), gv.ravel()
        face += rng.normal(0, 0.2 * step_m, face.shape)
        face[:, axis] += rng.normal(0, 0.0015, len(face))
        faces.append(face)
    surface = np.concatenate(faces)
    camera = np.array([0.6, 0.5, 0.7])
    edge = surface[rng.choice(len(surface), 300)]
    flying = edge + rng.uniform(0.0, 0.3, (300, 1)) * (camera - edge)
    far = rng.uniform(-1.0, 1.5, (100, 3))
    return rng.permutation(np.concatenate([surface, flying, far]))


def exact_counts(points: np.ndarray, radius: float) -> np.ndarray:
    """Other points within radius (inclusive), by one tree over the whole cloud."""
    return cKDTree(points).query_ball_point(points, radius, return_length=True) - 1


def reference_mask(points: np.ndarray, radius: float, eps: int) -> np.ndarray:
    return exact_counts(points, radius) >= eps


@pytest.mark.parametrize("decimate", [1, 3, 9])
@pytest.mark.parametrize(("radius", "eps"), [(0.05, 100), (0.013, 1), (0.02, 30)])
def test_scan_cloud_matches_exact_count(radius, eps, decimate):
    points = scan_cloud(3)[::decimate]  # dense surfaces to sparse ones whose counts sit near eps
    mask = radius_outlier_mask(points, radius, eps)
    assert np.array_equal(mask, reference_mask(points, radius, eps))
    assert 0 < mask.sum() < len(points)


@pytest.mark.parametrize(("radius", "eps"), [(0.05, 100), (0.013, 1)])
def test_far_apart_clusters_use_sorted_keys_and_stay_exact(radius, eps):
    # a second object 40 m away makes the grid's box far too big for dense counts
    points = scan_cloud(4)[::2]
    points = np.concatenate([points, points[::3] + [40.0, -25.0, 3.0]])
    mask = radius_outlier_mask(points, radius, eps)
    assert np.array_equal(mask, reference_mask(points, radius, eps))
    assert 0 < mask.sum() < len(points)


@settings(max_examples=40, deadline=None)
@given(
    cells=st.lists(st.tuples(*[st.integers(0, 14)] * 3), min_size=2, max_size=300),
    radius_units=st.integers(1, 7),
    eps=st.integers(1, 40),
)
def test_ties_stay_exact_when_the_grid_is_sparse(cells, radius_units, eps):
    # half the lattice moved 2^14 units away along x: sorted-key grids, with pairs at exactly r
    ijk = np.array(cells, dtype=np.int64)
    ijk[::2, 0] += 2**14
    d2 = ((ijk[:, None, :] - ijk[None, :, :]) ** 2).sum(axis=2)
    expected = (d2 <= radius_units**2).sum(axis=1) - 1 >= eps
    mask = radius_outlier_mask(ijk * 2.0**-8, radius_units * 2.0**-8, eps)
    assert np.array_equal(mask, expected)


def test_dense_surfaces_are_decided_by_the_grids(monkeypatch):
    # the fast path's point: almost no point of a dense scan is counted exactly
    queries = []
    counted = radius_filter_module._exact_counts

    def counting(xyz, which, radius_m):
        queries.append(len(which))
        return counted(xyz, which, radius_m)

    monkeypatch.setattr(radius_filter_module, "_exact_counts", counting)
    points = scan_cloud(5)
    for radius, eps in [(0.05, 100), (0.013, 1)]:
        queries.clear()
        assert np.array_equal(radius_outlier_mask(points, radius, eps), reference_mask(points, radius, eps))
        assert sum(queries) < 0.03 * len(points)


@pytest.mark.parametrize("far", [False, True])
@pytest.mark.parametrize("radius", [0.05, 0.013])
def test_points_near_the_radius_are_decided_exactly(radius, far):
    # around each centre a few points within r / 2 and a shell of 400 points either across r (0.97 r to
    # 1.03 r) or just beyond it (1.01 r to 1.1 r); eps at a centre's count and one above tests every bound
    # where it is tightest (far: a copy 40 m away makes the grids sparse)
    rng = np.random.default_rng(11)
    parts = []
    for i, centre in enumerate(np.stack(np.meshgrid(*[[0.0, 3 * radius]] * 3), axis=-1).reshape(-1, 3)):
        shell = rng.normal(size=(400, 3))
        shell /= np.linalg.norm(shell, axis=1, keepdims=True)
        shell *= rng.uniform(*((0.97, 1.03) if i % 2 else (1.01, 1.1)), (400, 1)) * radius
        parts += [centre[None], centre + shell, centre + rng.uniform(-0.25, 0.25, (40, 3)) * radius]
    centres = np.cumsum([0] + [len(part) for part in parts])[:-1:3]
    points = np.concatenate(parts)
    if far:
        points = np.concatenate([points, points[::2] + [40.0, -25.0, 3.0]])
    counts = exact_counts(points, radius)
    for eps in sorted({int(c) + d for c in counts[centres] for d in (0, 1)}):
        assert np.array_equal(radius_outlier_mask(points, radius, eps), counts >= eps)


def test_neighbours_of_a_lone_point_beyond_half_a_radius_are_counted():
    # only the lone point is undecided; its neighbours sit 0.6 r to r away in a dense blob
    rng = np.random.default_rng(12)
    blob = rng.uniform(0.0, 0.02, (3000, 3))
    lone = np.array([[0.02 + 0.6 * 0.05, 0.01, 0.01]])
    points = np.concatenate([blob, lone])
    counts = exact_counts(points, 0.05)
    for eps in (int(counts[-1]), int(counts[-1]) + 1):
        assert np.array_equal(radius_outlier_mask(points, 0.05, eps), counts >= eps)
