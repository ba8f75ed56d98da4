"""Screw-axis estimator: register the moving part's frames rigidly, then fit one joint to all the motions.

Each new frame costs one registration: its moving part (sparse source) onto the keyframe (dense
target with normals), by Open3D point-to-plane ICP with a Tukey kernel. The part grows as the object
opens, so when the keyframe no longer covers most of the new frame, the new frame becomes the
keyframe and the window's earlier frames are registered onto it directly (each is mostly a subset of
the newer part): the motions never chain through the small, poorly constrained clouds of the first
frames, and those frames are left out of the joint fit. The motions relative to the window start are
fitted jointly by a prismatic and a revolute model (see `ScrewEstimator.estimate`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.types import Axis, AxisResult, Box, JointType, NoAxis

_REG = o3d.pipelines.registration


@dataclass(frozen=True)
class _Cloud:
    """A frame's moving part: the finite input points, a sparse downsampled source for registration
    (also as an array), the body box it was cut from, and a fingerprint of the input."""

    raw: np.ndarray
    source: o3d.geometry.PointCloud
    points: np.ndarray
    box: Box
    fingerprint: tuple[int, bytes]


@dataclass(frozen=True)
class _Registration:
    """Motion (4x4, base frame) taking the keyframe's part to the frame's, and how much of it matched."""

    motion: np.ndarray
    fitness: float


@dataclass(frozen=True)
class _JointFit:
    direction: np.ndarray
    point: np.ndarray
    rms_m: float
    bic: float


class ScrewEstimator(AxisEstimator):
    """Screw axis of the moving part's rigid motion over the whole window (any axis orientation).

    voxel_m: downsampling voxel; max_source / max_target: points used per registration (random,
    fixed seed; time); min_points: points a frame needs after downsampling; min_fitness: share of
    a frame's source that must match the keyframe; keyframe_coverage: a frame becomes the next
    keyframe when the keyframe saw less than this share of it; min_share: frames with fewer points
    than this share of the keyframe's are left out of the joint fit; overlap_margin_m: how far outside
    the body box a point must have been to count as seen (at least the margin used to cut the moving
    part);
    min_travel_m / min_rotation_deg: motion below both gives NoAxis; noise_floor_m: registration
    noise (sigma0 of the BIC); max_radius_m: a revolute fit whose axis lies farther than this from
    the moving part counts as prismatic (a drawer that wobbles). `registrations` counts the new frames
    registered (one each), `rekey_registrations` the earlier frames registered again onto a new keyframe.
    """

    name = "screw"

    def __init__(
        self,
        voxel_m: float = 0.005,
        max_source: int = 2000,
        max_target: int = 6000,
        min_points: int = 100,
        min_fitness: float = 0.3,
        keyframe_coverage: float = 0.8,
        overlap_margin_m: float = 0.02,
        min_travel_m: float = 0.01,
        min_rotation_deg: float = 2.0,
        noise_floor_m: float = 0.001,
        max_radius_m: float = 3.0,
        min_share: float = 0.5,
        use_gripper: bool = False,
        part_noise_m: float = 0.003,
        grip_noise_m: float = 0.001,
        grip_gate_m: float = 0.005,
    ) -> None:
        self.voxel_m = voxel_m
        self.max_source = max_source
        self.max_target = max_target
        self.min_points = min_points
        self.min_fitness = min_fitness
        self.keyframe_coverage = keyframe_coverage
        self.overlap_margin_m = overlap_margin_m
        self.min_travel_m = min_travel_m
        self.min_rotation_deg = min_rotation_deg
        self.noise_floor_m = noise_floor_m
        self.max_radius_m = max_radius_m
        self.min_share = min_share
        self.use_gripper = use_gripper
        self.part_noise_m = part_noise_m
        self.grip_noise_m = grip_noise_m
        self.grip_gate_m = grip_gate_m
        self.registrations = 0
        self.rekey_registrations = 0
        self.reset()

    def reset(self) -> None:
        """Forget cached clouds, motions and the keyframe (done automatically when a frame index is reused)."""
        self._clouds: dict[int, _Cloud] = {}
        self._motions: dict[int, _Registration] = {}  # keyframe -> frame, for the frames that matched
        self._seen: set[int] = set()  # frames registered (or tried) since the last reset
        self._keyframe: int | None = None
        self._keyframe_target = o3d.geometry.PointCloud()
        self._keyframe_centre = np.zeros(3)
        self._failures = 0

    def estimate(self, window: Sequence[Observation], joint: JointType | None = None) -> AxisResult:
        """The joint axis from the moving part's motion over the window.

        Only frames whose part has at least min_share of the keyframe's points take part (the first
        frames of a pull hold little more than the handle, whose registration can slide). Their
        motions are taken relative to the oldest of them; the model points are the keyframe's.
        Prismatic: direction = principal direction of the part centroid's path (and the gripper's,
        with use_gripper), along the motion; origin = centroid of the model points at the window
        start. Revolute: direction from least squares over R_k w = w (signed so the observed motion
        is a positive rotation); axis point = the centre of the circles that the part's centroid (and
        the gripper) run through at the registered turns about w (`_revolute`). When the part is a
        plate (a door panel), w is projected onto its plane: a hinge lies in its door's plane, and the
        rotation about a plate's normal is what registration measures worst. Origin = the axis point
        nearest the latest moving-part centroid, radius_m = distance from that centroid to the axis.
        residual_m = RMS distance between the registered and the joint model's positions of the model
        points; confidence = fitness (1 from 90 %) x motion (1 from 5 cm or 10 deg) x
        1 / (1 + (residual / 2 mm)^2).

        Joint type when `joint` is None: BIC = n ln(rms^2 + sigma0^2) + k ln n with n = 6 per pose
        (what a registration measures), k = poses + 2 (prismatic) or poses + 4 (revolute); the lower
        wins, except that a revolute axis farther than max_radius_m from the part means prismatic.
        """
        if len(window) < 2:
            return NoAxis(f"need at least 2 frames of the moving part, got {len(window)}")
        cached = [self._clouds[o.index].fingerprint for o in window if o.index in self._clouds]
        if cached != [_fingerprint(o) for o in window if o.index in self._clouds]:
            self.reset()  # a frame index now holds other points: a new episode
        clouds = {o.index: self._cloud(o) for o in window}
        usable = [o.index for o in window if len(clouds[o.index].points) >= self.min_points]
        self._forget_all_but(clouds)
        if len(usable) < 2:
            counts = [len(clouds[o.index].points) for o in window]
            return NoAxis(
                f"too few moving-part points: {max(counts)} at most after {self.voxel_m * 1000:.0f} mm "
                f"downsampling, need {self.min_points} in at least 2 frames",
                {"points": counts},
            )
        for index in usable:
            if index not in self._seen and index > max(self._seen, default=-1):
                self._add(index, clouds)
        latest = self._motions.get(usable[-1])
        if latest is None:
            return NoAxis(
                f"registration of frame {usable[-1]} failed: less than {self.min_fitness:.0%} of its moving "
                "part matches the keyframe; the part changed too much or too fast, or the segmentation jumped",
                {"frame": usable[-1]},
            )
        enough = self.min_share * len(clouds[self._keyframe].raw) if self._keyframe in clouds else 0.0
        used = [i for i in usable if i in self._motions and len(clouds[i].raw) >= enough]
        if len(used) < 2:
            return NoAxis(f"only {len(used)} frame of the window registered with enough points; waiting for more")
        start = self._motions[used[0]].motion
        poses = np.array([self._motions[i].motion @ np.linalg.inv(start) for i in used[1:]])
        model = self._keyframe_points @ start[:3, :3].T + start[:3, 3]
        fitness = min([self._motions[i].fitness for i in used] + [0.9]) / 0.9
        grips = {o.index: np.asarray(o.gripper_pose, float)[:3, 3]
                 for o in window if o.gripper_pose is not None and self.use_gripper}
        at_used = np.array([grips[i] for i in used]) if all(i in grips for i in used) else None
        everywhere = np.array(list(grips.values())) if len(grips) >= 2 else None
        return self._fit(poses, model, clouds[usable[-1]].points, fitness, joint, at_used, everywhere)

    def _cloud(self, observation: Observation) -> _Cloud:
        """The frame's cloud, cached by frame index."""
        if observation.index in self._clouds:
            return self._clouds[observation.index]
        points = np.asarray(observation.moving, float).reshape(-1, 3)
        points = points[np.all(np.isfinite(points), axis=1)]
        # A random subset (fixed seed), then the voxel grid: cheap whatever the input size, and not a
        # coarse grid, whose cell centres would stick to the grid as surfaces slide along themselves.
        subset = points[np.random.default_rng(0).integers(0, len(points), self.max_source)] if len(
            points) > self.max_source else points
        source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(subset)).voxel_down_sample(self.voxel_m)
        fingerprint = _fingerprint(observation)
        cloud = _Cloud(points, source, np.asarray(source.points), observation.body_box, fingerprint)
        self._clouds[observation.index] = cloud
        return cloud

    def _forget_all_but(self, clouds: dict[int, _Cloud]) -> None:
        keep = set(clouds) | {self._keyframe}
        self._clouds = {i: c for i, c in self._clouds.items() if i in keep}
        self._motions = {i: m for i, m in self._motions.items() if i in keep}

    def _make_keyframe(self, index: int) -> None:
        """The frame's dense cloud with normals becomes the target of the registrations."""
        target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self._clouds[index].raw))
        target = target.voxel_down_sample(self.voxel_m)
        if len(target.points) > self.max_target:
            keep = np.random.default_rng(0).permutation(len(target.points))[: self.max_target]
            target = target.select_by_index(np.sort(keep))
        target.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(10))
        self._keyframe, self._keyframe_target = index, target
        self._keyframe_points = self._clouds[index].points
        self._keyframe_centre = self._keyframe_points.mean(axis=0)

    def _start_chain(self, index: int) -> None:
        self._make_keyframe(index)
        self._motions = {index: _Registration(np.eye(4), 1.0)}
        self._failures = 0

    def _add(self, index: int, clouds: dict[int, _Cloud]) -> None:
        """Register a new frame onto the keyframe; rekey when the keyframe saw too little of it.

        The source is the part of the frame the keyframe saw: its points that, moved back to the
        keyframe, lie outside the body box grown by overlap_margin_m (the rest came out of the box
        later and would pull the fit). The start is the previous frame's motion; when the match is
        worse than the last frame's, a search as wide as the last step runs too. A frame that fails
        is skipped; a second failure in a row starts a new chain at that frame (a bad keyframe).
        """
        self._seen.add(index)
        if self._keyframe is None or not self._motions:
            self._start_chain(index)
            return
        previous = [i for i in sorted(self._motions) if i < index][-2:]
        guess = self._motions[previous[-1]].motion
        cloud = clouds[index]
        back = (cloud.points - guess[:3, 3]) @ guess[:3, :3]
        seen = ~cloud.box.contains(back, self.overlap_margin_m)
        coverage = float(seen.mean())
        source = cloud.source
        if seen.sum() >= self.min_points:
            source = source.select_by_index(np.flatnonzero(seen))
        # ICP finds the transform taking the frame's points onto the keyframe's: the inverse motion.
        fine_m = 2 * self.voxel_m
        result = self._icp(source, np.linalg.inv(guess), (fine_m,))
        if result.fitness < 0.9 * self._motions[previous[-1]].fitness:
            centre = guess @ np.append(self._keyframe_centre, 1.0)
            step = guess @ np.linalg.inv(self._motions[previous[0]].motion) @ centre - centre
            reach_m = max(5 * self.voxel_m, 1.5 * float(np.linalg.norm(step)))
            wide = self._icp(source, np.linalg.inv(guess), (reach_m, fine_m))
            result = max(result, wide, key=lambda r: r.fitness)
        self.registrations += 1
        if result.fitness >= self.min_fitness:
            self._failures = 0
            self._motions[index] = _Registration(np.linalg.inv(result.transformation), float(result.fitness))
            if coverage < self.keyframe_coverage:
                self._rekey(index, clouds)
        else:  # skip the frame; after two failures in a row, suspect the keyframe and start over here
            self._failures += 1
            if self._failures >= 2:
                self._start_chain(index)

    def _rekey(self, index: int, clouds: dict[int, _Cloud]) -> None:
        """Make the frame the keyframe and register the earlier frames onto it directly (each is
        mostly a subset of the newer, larger part), starting from their motions via the old keyframe."""
        old = self._motions
        to_old = np.linalg.inv(old[index].motion)
        self._make_keyframe(index)
        self._motions = {index: _Registration(np.eye(4), 1.0)}
        for j, registration in old.items():
            if j == index or j not in clouds:
                continue
            guess = registration.motion @ to_old
            result = self._icp(clouds[j].source, np.linalg.inv(guess), (2 * self.voxel_m,))
            self.rekey_registrations += 1
            if result.fitness >= self.min_fitness:
                self._motions[j] = _Registration(np.linalg.inv(result.transformation), float(result.fitness))

    def _icp(self, source: o3d.geometry.PointCloud, transform: np.ndarray, distances_m: tuple[float, ...]):
        """Point-to-plane ICP onto the keyframe with a Tukey kernel, once per correspondence distance."""
        for distance_m in distances_m:
            result = _REG.registration_icp(
                source, self._keyframe_target, distance_m, transform,
                _REG.TransformationEstimationPointToPlane(_REG.TukeyLoss(k=distance_m)),
                _REG.ICPConvergenceCriteria(relative_fitness=1e-5, relative_rmse=1e-5, max_iteration=20),
            )
            transform = result.transformation
        return result

    def _fit(
        self, poses: np.ndarray, start: np.ndarray, latest: np.ndarray, fitness: float,
        joint: JointType | None, path_used: np.ndarray | None, path_all: np.ndarray | None,
    ) -> AxisResult:
        """Fit the joint to the motions `poses` (K,4,4) of the window-start points `start` (M,3).

        The gripper's positions, when known: `path_used` at the start and after each motion (for a
        hinge, which needs the turns), `path_all` in every frame of the window (for a line)."""
        sample = start[np.linspace(0, len(start) - 1, min(len(start), 200)).astype(int)]
        moved = np.einsum("kij,mj->kmi", poses[:, :3, :3], sample) + poses[:, None, :3, 3]
        centroid = sample.mean(axis=0)
        travel_m = float(np.max(np.linalg.norm(moved.mean(axis=1) - centroid, axis=1)))
        rotation_deg = float(np.degrees(np.max(Rotation.from_matrix(poses[:, :3, :3]).magnitude())))
        if travel_m < self.min_travel_m and rotation_deg < self.min_rotation_deg:
            return NoAxis(
                f"not enough motion yet: {travel_m * 1000:.1f} mm of {self.min_travel_m * 1000:.0f} mm "
                f"and {rotation_deg:.1f} deg of {self.min_rotation_deg:.0f} deg",
                {"travel_m": travel_m, "rotation_deg": rotation_deg},
            )
        n = 6 * len(poses)
        fits = {}
        if joint is not JointType.REVOLUTE:
            fits[JointType.PRISMATIC] = self._prismatic(sample, moved, n, path_all)
        if joint is not JointType.PRISMATIC:
            fits[JointType.REVOLUTE] = self._revolute(poses, sample, moved, n, path_used)
        handle = latest.mean(axis=0)
        radius_m = _distance_to_line(handle, fits[JointType.REVOLUTE]) if JointType.REVOLUTE in fits else 0.0
        far = radius_m > self.max_radius_m
        if joint is None:
            joint = JointType.PRISMATIC if far else min(fits, key=lambda j: fits[j].bic)
        elif joint is JointType.REVOLUTE and far:
            return NoAxis(
                f"the motion is too straight to locate a hinge: the fitted axis is more than "
                f"{self.max_radius_m:.1f} m from the moving part",
                {"radius_m": radius_m},
            )
        fit = fits[joint]
        motion = min(1.0, max(travel_m / 0.05, rotation_deg / 10.0))
        confidence = float(np.clip(fitness * motion / (1 + (fit.rms_m / 0.002) ** 2), 0.0, 1.0))
        if joint is JointType.PRISMATIC:
            return Axis(joint, centroid, fit.direction, confidence=confidence, residual_m=fit.rms_m)
        origin = fit.point + ((handle - fit.point) @ fit.direction) * fit.direction
        return Axis(
            joint, origin, fit.direction, confidence=confidence, residual_m=fit.rms_m, radius_m=radius_m
        )

    def _bic(self, rms_m: float, n: int, k: int) -> float:
        return float(n * np.log(rms_m**2 + self.noise_floor_m**2) + k * np.log(n))

    def _tracks(self, sample: np.ndarray, moved: np.ndarray, path: np.ndarray | None) -> list[tuple[np.ndarray, float]]:
        """Positions to fit a joint to, each with its noise: the part's centroid at the start and after
        each motion, and the gripper's `path` when given (use_gripper)."""
        tracks = [(np.vstack([sample.mean(axis=0), moved.mean(axis=1)]), self.part_noise_m)]
        return tracks if path is None else tracks + [(path, self.grip_noise_m)]

    def _prismatic(self, sample: np.ndarray, moved: np.ndarray, n: int, path: np.ndarray | None) -> _JointFit:
        """Points move by s_k d: d = principal direction of the tracks' positions (each about its mean,
        weighted by 1 / its noise), along the motion; a gripper path farther than grip_gate_m RMS from
        its line is left out."""
        tracks = self._tracks(sample, moved, path)
        d = _principal_direction(tracks)
        if len(tracks) > 1 and _line_miss(tracks[1][0], d) > self.grip_gate_m:
            d = _principal_direction(tracks[:1])
        shifts = moved.mean(axis=1) - sample.mean(axis=0)
        travel = shifts @ d
        if travel[np.argmax(np.abs(travel))] < 0:
            d, travel = -d, -travel
        predicted = sample[None] + travel[:, None, None] * d
        rms = float(np.sqrt(np.mean(np.sum((moved - predicted) ** 2, axis=2))))
        return _JointFit(d, sample.mean(axis=0), rms, self._bic(rms, n, len(moved) + 2))

    def _revolute(
        self, poses: np.ndarray, sample: np.ndarray, moved: np.ndarray, n: int, path: np.ndarray | None
    ) -> _JointFit:
        """Rotation about the line (w, a).

        w: least squares over R_k w = w, projected into a plate's plane, signed so the motion turns
        positively. The turns are the registered rotations' angles about w (what registration
        measures best). a: the centre of the circles the part's centroid and, when given, the
        gripper `path` run through at those turns (`_circle_centre`); a path that misses its circle
        by more than grip_gate_m RMS (the grasp slipped) is left out.
        """
        rotations = poses[:, :3, :3]
        m = rotations - np.eye(3)
        w = np.linalg.eigh(np.einsum("kji,kjl->il", m, m))[1][:, 0]
        plate = _plate_normal(sample)
        if plate is not None and abs(w @ plate) < np.sin(np.radians(30)):
            w = w - (w @ plate) * plate
            w = w / np.linalg.norm(w)
        rotvecs = Rotation.from_matrix(rotations).as_rotvec()
        if rotvecs.sum(axis=0) @ w < 0:
            w = -w
        turns = Rotation.from_rotvec(np.outer(rotvecs @ w, w)).as_matrix()
        anchor = w @ sample.mean(axis=0)
        tracks = self._tracks(sample, moved, path)
        a, misses = _circle_centre(w, turns, tracks, anchor)
        if len(tracks) > 1 and misses[1] > self.grip_gate_m:
            a, _ = _circle_centre(w, turns, tracks[:1], anchor)
        predicted = np.einsum("kij,mj->kmi", turns, sample - a) + a
        rms = float(np.sqrt(np.mean(np.sum((moved - predicted) ** 2, axis=2))))
        return _JointFit(w, a, rms, self._bic(rms, n, len(moved) + 4))


class ScrewGripEstimator(ScrewEstimator):
    """The screw estimator that also fits the held handle's path (the gripper poses from forward
    kinematics): the part's registered turns with the gripper's positions, which locate a hinge and a
    drawer's direction better than the part's sliding centroid. Without gripper poses it is `screw`."""

    name = "screw-grip"

    def __init__(self, **options) -> None:
        super().__init__(**{"use_gripper": True, **options})


def _circle_centre(
    w: np.ndarray, turns: np.ndarray, tracks: list[tuple[np.ndarray, float]], anchor: float
) -> tuple[np.ndarray, list[float]]:
    """The point a of the axis (direction w, a @ w = anchor) about which each track of positions
    p_0..p_K (start, then after each turn) moves: p_k = a + R_k v, one lever v per track, every
    track weighted by 1 / its noise (m). Returns a and each track's RMS residual (m)."""
    rotations = np.concatenate([np.eye(3)[None], turns])
    cols = 3 + 3 * len(tracks)
    rows, rhs = [], []
    for j, (positions, sigma) in enumerate(tracks):
        block = np.zeros((len(rotations), 3, cols))
        block[:, :, :3] = np.eye(3)
        block[:, :, 3 + 3 * j: 6 + 3 * j] = rotations
        rows.append(block.reshape(-1, cols) / sigma)
        rhs.append(np.asarray(positions).ravel() / sigma)
    rows.append(np.append(w, np.zeros(cols - 3))[None] * 1e3)
    rhs.append([anchor * 1e3])
    x = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    a = x[:3]
    rms = [
        float(np.sqrt(np.mean(np.sum((positions - a - rotations @ x[3 + 3 * j: 6 + 3 * j]) ** 2, axis=1))))
        for j, (positions, _) in enumerate(tracks)
    ]
    return a, rms


def _principal_direction(tracks: list[tuple[np.ndarray, float]]) -> np.ndarray:
    """The unit direction along which the tracks' positions spread most (each about its own mean,
    weighted by 1 / its noise)."""
    centred = np.vstack([(positions - positions.mean(axis=0)) / sigma for positions, sigma in tracks])
    return np.linalg.svd(centred, full_matrices=False)[2][0]


def _line_miss(positions: np.ndarray, direction: np.ndarray) -> float:
    """RMS distance (m) of positions from the line through their mean along `direction`."""
    offsets = positions - positions.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum((offsets - np.outer(offsets @ direction, direction)) ** 2, axis=1))))


def _fingerprint(observation: Observation) -> tuple[int, bytes]:
    """A cheap identity check of a frame's points: their count and eight of them."""
    points = np.asarray(observation.moving, float).reshape(-1, 3)
    return len(points), points[:: max(1, len(points) // 8)].tobytes()


def _distance_to_line(point: np.ndarray, fit: _JointFit) -> float:
    offset = point - fit.point
    return float(np.linalg.norm(offset - (offset @ fit.direction) * fit.direction))


def _plate_normal(points: np.ndarray) -> np.ndarray | None:
    """Normal of the plate the points mostly lie on (trimmed PCA), None when they are not a plate."""
    kept = points
    for _ in range(3):
        centre = kept.mean(axis=0)
        _, spread, axes = np.linalg.svd(kept - centre, full_matrices=False)
        distance = np.abs((points - centre) @ axes[2])
        kept = points[distance <= max(3 * np.median(distance), 0.002)]
    if len(kept) < 0.6 * len(points) or spread[2] > 0.1 * spread[1]:
        return None
    return axes[2]
