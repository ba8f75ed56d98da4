"""The dominant plane of a point set (RANSAC), deterministic: the same points give the same plane, run after run
(Open3D's parallel RANSAC does not, to the last digits)."""

from __future__ import annotations

import numpy as np

RANSAC_TRIALS = 200  # planes tried: the chance of missing a plane holding half the points is 0.875^200 ~ 3e-12


def dominant_plane(points: np.ndarray, tolerance_m: float, seed: int = 0) -> np.ndarray:
    """Indices of the points within `tolerance_m` of the plane that holds the most of them (RANSAC over
    RANSAC_TRIALS planes through three points drawn with `seed`); empty with fewer than three points."""
    pts = np.asarray(points, float).reshape(-1, 3)
    if len(pts) < 3:
        return np.zeros(0, int)
    rng = np.random.default_rng(seed)
    triples = pts[rng.integers(0, len(pts), (RANSAC_TRIALS, 3))]
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    length = np.linalg.norm(normals, axis=1)
    good = length > 1e-12
    normals, anchors = normals[good] / length[good, None], triples[good, 0]
    if len(normals) == 0:
        return np.zeros(0, int)
    counts = np.zeros(len(normals), int)
    for start in range(0, len(pts), 4096):  # (points x planes) distances in blocks
        block = pts[start:start + 4096]
        counts += np.count_nonzero(np.abs(block @ normals.T - np.sum(anchors * normals, axis=1)) <= tolerance_m,
                                   axis=0)
    best = int(np.argmax(counts))
    return np.flatnonzero(np.abs((pts - anchors[best]) @ normals[best]) <= tolerance_m)
