"""Rigid registration of a moving part's frames onto a keyframe: Open3D point-to-plane ICP, Tukey kernel.

Stateless functions: clouds in, motions out. A motion (4x4, base frame) takes the keyframe's part to a
frame's; ICP estimates its inverse, which moves the frame's points onto the keyframe's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from deploy.geometry.types import Box

# Open3D's multithreaded ICP sums in a different order from run to run: one thread makes every registration,
# and so every episode and benchmark, reproducible.
o3d.utility.set_max_threads(1)

_REG = o3d.pipelines.registration
_TARGET_NORMAL_NEIGHBOURS = 10


@dataclass(frozen=True)
class PartCloud:
    """A frame's moving part: the finite input points `raw`, the sparse downsampled `source` for
    registration (also as the array `points`), the body `box` it was cut from, and a `fingerprint`
    of the input."""

    raw: np.ndarray
    source: o3d.geometry.PointCloud
    points: np.ndarray
    box: Box
    fingerprint: tuple[int, bytes]


@dataclass(frozen=True)
class Keyframe:
    """The registration target: frame `index`'s dense part with normals (`target`), its sparse
    `points` (the model points of the joint fit) and their `centre`, and the target's unit `normals`."""

    index: int
    target: o3d.geometry.PointCloud
    points: np.ndarray
    centre: np.ndarray
    normals: np.ndarray


@dataclass(frozen=True)
class Registration:
    """Motion (4x4, base frame) taking the keyframe's part to the frame's, and the share of the
    frame's source that matched (0-1)."""

    motion: np.ndarray
    fitness: float


def fingerprint(moving: np.ndarray) -> tuple[int, bytes]:
    """A cheap identity check of a frame's points: their count and eight of them."""
    points = np.asarray(moving, float).reshape(-1, 3)
    return len(points), points[:: max(1, len(points) // 8)].tobytes()


def part_cloud(moving: np.ndarray, box: Box, voxel_m: float, max_source: int) -> PartCloud:
    """The frame's moving part (N,3) as a registration source: at most `max_source` random points
    (fixed seed), then a `voxel_m` grid. Sampling first keeps the cost flat whatever the input size,
    and lets a fine grid be used: a coarse grid's cell centres would stick to the grid as surfaces
    slide along themselves."""
    points = np.asarray(moving, float).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    subset = points[np.random.default_rng(0).integers(0, len(points), max_source)] if len(
        points) > max_source else points
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(subset)).voxel_down_sample(voxel_m)
    return PartCloud(points, source, np.asarray(source.points), box, fingerprint(moving))


def make_keyframe(index: int, cloud: PartCloud, voxel_m: float, max_target: int) -> Keyframe:
    """Frame `index` as the target: its raw part on a `voxel_m` grid, at most `max_target` points
    (random, fixed seed), with normals from 10 neighbours."""
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.raw))
    target = target.voxel_down_sample(voxel_m)
    if len(target.points) > max_target:
        keep = np.random.default_rng(0).permutation(len(target.points))[:max_target]
        target = target.select_by_index(np.sort(keep))
    target.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(_TARGET_NORMAL_NEIGHBOURS))
    return Keyframe(index, target, cloud.points, cloud.points.mean(axis=0), np.asarray(target.normals))


def icp(
    source: o3d.geometry.PointCloud, keyframe: Keyframe, guess: np.ndarray, distances_m: tuple[float, ...]
) -> Registration:
    """The motion of `source` from the keyframe, starting at the motion `guess`: point-to-plane ICP of
    the source onto the keyframe with a Tukey kernel, once per correspondence distance (m), each
    run starting where the previous one ended."""
    transform = np.linalg.inv(guess)
    for distance_m in distances_m:
        result = _REG.registration_icp(
            source, keyframe.target, distance_m, transform,
            _REG.TransformationEstimationPointToPlane(_REG.TukeyLoss(k=distance_m)),
            _REG.ICPConvergenceCriteria(relative_fitness=1e-5, relative_rmse=1e-5, max_iteration=20),
        )
        transform = result.transformation
    return Registration(np.linalg.inv(result.transformation), float(result.fitness))


def register_frame(
    cloud: PartCloud, keyframe: Keyframe, guess: Registration, before_guess: np.ndarray, *,
    voxel_m: float, overlap_margin_m: float, min_points: int,
) -> tuple[Registration, float]:
    """The frame's motion from the keyframe, and the share of its points the keyframe saw (0-1).

    `guess` is the previous registered frame's registration, `before_guess` the motion of the one
    before it (or `guess.motion` again). The source is the part of the frame the keyframe saw: its
    points that, moved back to the keyframe by the guess, lie outside the body box grown by
    `overlap_margin_m` (the rest came out of the box later and would pull the fit); all its points
    when fewer than `min_points` remain. ICP runs at 2 `voxel_m`; when it matches less than 90 % of
    what the guess matched, a search as wide as the last step (at least 5 `voxel_m`) runs too and the
    better match wins.
    """
    motion = guess.motion
    back = (cloud.points - motion[:3, 3]) @ motion[:3, :3]
    seen = ~cloud.box.contains(back, overlap_margin_m)
    coverage = float(seen.mean())
    source = cloud.source
    if seen.sum() >= min_points:
        source = source.select_by_index(np.flatnonzero(seen))
    fine_m = 2 * voxel_m
    result = icp(source, keyframe, motion, (fine_m,))
    if result.fitness < 0.9 * guess.fitness:
        centre = motion @ np.append(keyframe.centre, 1.0)
        step = motion @ np.linalg.inv(before_guess) @ centre - centre
        reach_m = max(5 * voxel_m, 1.5 * float(np.linalg.norm(step)))
        wide = icp(source, keyframe, motion, (reach_m, fine_m))
        result = max(result, wide, key=lambda r: r.fitness)
    return result, coverage
