"""Screw-axis estimator: register the moving part's frames rigidly, then fit one joint to all the motions.

Each new frame costs one registration: its moving part (sparse source) onto the keyframe (dense
target with normals), see `screw_registration`. The part grows as the object opens, so when the
keyframe no longer covers most of the new frame, the new frame becomes the keyframe and the window's
earlier frames are registered onto it directly (each is mostly a subset of the newer part): the
motions never chain through the small, poorly constrained clouds of the first frames, and those
frames are left out of the joint fit. The motions relative to the window start are fitted jointly by
a prismatic and a revolute model, see `screw_fit.fit_screw_joint`. This module keeps the state: the
frames' clouds and motions, the keyframe, and the window.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from deploy.geometry.estimators.base import AxisEstimator, Observation
from deploy.geometry.estimators.screw_config import ScrewConfig
from deploy.geometry.estimators.screw_fit import fit_screw_joint
from deploy.geometry.estimators.screw_registration import (
    Keyframe,
    PartCloud,
    Registration,
    fingerprint,
    icp,
    make_keyframe,
    part_cloud,
    register_frame,
)
from deploy.geometry.types import AxisResult, JointType, NoAxis

_DEFAULT_CONFIG = ScrewConfig()  # frozen: one instance serves every estimator built without a config
_REKEY_MARGIN = 0.05  # share of a frame's points: smaller fitness differences between two motions are noise
# (a plate matches about as well slid along itself)


class ScrewEstimator(AxisEstimator):
    """Screw axis of the moving part's rigid motion over the window (any axis orientation).

    Settings: `ScrewConfig`. Clouds, motions and the keyframe persist across calls, so a sliding
    window costs one registration per new frame. `registrations` counts the new frames registered,
    `rekey_registrations` the earlier frames registered again onto a new keyframe.
    """

    name = "screw"

    def __init__(self, config: ScrewConfig = _DEFAULT_CONFIG) -> None:
        self.config = config
        self.registrations = 0
        self.rekey_registrations = 0
        self.reset()

    def reset(self) -> None:
        """Forget cached clouds, motions and the keyframe (done automatically when a frame index is reused)."""
        self._clouds: dict[int, PartCloud] = {}
        self._motions: dict[int, Registration] = {}  # keyframe -> frame, for the frames that matched
        self._seen: set[int] = set()  # frames registered (or tried) since the last reset
        self._keyframe: Keyframe | None = None
        self._failures = 0
        self._held: dict[int, np.ndarray] = {}  # frame -> gripper position, over the hold the window ends in

    def estimate(self, window: Sequence[Observation], joint: JointType | None = None) -> AxisResult:
        """The joint axis from the moving part's motion over the window (`fit_screw_joint`).

        Frames with fewer than min_points points are skipped. Only frames whose part has at least
        min_share of the keyframe's points take part in the fit (the first frames of a pull hold
        little more than the handle, whose registration can slide). Their motions are taken relative
        to the oldest of them; the model points are the keyframe's, moved to the window start.
        """
        config = self.config
        if len(window) < 2:
            return NoAxis(f"need at least 2 frames of the moving part, got {len(window)}")
        cached = [self._clouds[o.index].fingerprint for o in window if o.index in self._clouds]
        if cached != [fingerprint(o.moving) for o in window if o.index in self._clouds]:
            self.reset()  # a frame index now holds other points: a new episode
        self._held = held_path(self._held, window)
        clouds = {o.index: self._cloud(o) for o in window}
        usable = [o.index for o in window if len(clouds[o.index].points) >= config.min_points]
        self._forget_all_but(clouds)
        if len(usable) < 2:
            counts = [len(clouds[o.index].points) for o in window]
            return NoAxis(
                f"too few moving-part points: {max(counts)} at most after {config.voxel_m * 1000:.0f} mm "
                f"downsampling, need {config.min_points} in at least 2 frames",
                {"points": counts},
            )
        for index in usable:
            if index not in self._seen and index > max(self._seen, default=-1):
                self._add(index, clouds)
        if usable[-1] not in self._motions:
            return NoAxis(
                f"registration of frame {usable[-1]} failed: less than {config.min_fitness:.0%} of its moving "
                "part matches the keyframe; the part changed too much or too fast, or the segmentation jumped",
                {"frame": usable[-1]},
            )
        keyframe = self._keyframe
        enough = config.min_share * len(clouds[keyframe.index].raw) if keyframe.index in clouds else 0.0
        used = [i for i in usable if i in self._motions and len(clouds[i].raw) >= enough]
        if len(used) < 2:
            return NoAxis(f"only {len(used)} frame of the window registered with enough points; waiting for more")
        start = self._motions[used[0]].motion
        poses = np.array([self._motions[i].motion @ np.linalg.inv(start) for i in used[1:]])
        model = keyframe.points @ start[:3, :3].T + start[:3, 3]
        fitness = min(self._motions[i].fitness for i in used)
        latest_centre = clouds[usable[-1]].points.mean(axis=0)
        grip_at_poses, grip_path = _gripper_positions(window, used, self._held) if self.use_gripper else (None, None)
        turn = start[:3, :3]
        surface = (np.asarray(keyframe.target.points) @ turn.T + start[:3, 3], keyframe.normals @ turn.T)
        return fit_screw_joint(poses, model, latest_centre, fitness, joint, config, grip_at_poses, grip_path,
                               surface)

    def _cloud(self, observation: Observation) -> PartCloud:
        """The frame's cloud, cached by frame index."""
        if observation.index not in self._clouds:
            self._clouds[observation.index] = part_cloud(
                observation.moving, observation.body_box, self.config.voxel_m, self.config.max_source)
        return self._clouds[observation.index]

    def _forget_all_but(self, clouds: dict[int, PartCloud]) -> None:
        keep = set(clouds) | ({self._keyframe.index} if self._keyframe is not None else set())
        self._clouds = {i: c for i, c in self._clouds.items() if i in keep}
        self._motions = {i: m for i, m in self._motions.items() if i in keep}

    def _make_keyframe(self, index: int) -> None:
        """The frame becomes the keyframe, the only frame with a motion (the identity)."""
        self._keyframe = make_keyframe(index, self._clouds[index], self.config.voxel_m, self.config.max_target)
        self._motions = {index: Registration(np.eye(4), 1.0)}

    def _start_chain(self, index: int) -> None:
        self._make_keyframe(index)
        self._failures = 0

    def _add(self, index: int, clouds: dict[int, PartCloud]) -> None:
        """Register a new frame onto the keyframe, starting from the previous frame's motion
        (`register_frame`); rekey when the keyframe saw less than keyframe_coverage of it. A frame
        that fails is skipped; a second failure in a row starts a new chain at that frame (a bad
        keyframe)."""
        self._seen.add(index)
        if self._keyframe is None or not self._motions:
            self._start_chain(index)
            return
        config = self.config
        previous = [i for i in sorted(self._motions) if i < index][-2:]
        registration, coverage = register_frame(
            clouds[index], self._keyframe, self._motions[previous[-1]], self._motions[previous[0]].motion,
            voxel_m=config.voxel_m, overlap_margin_m=config.overlap_margin_m, min_points=config.min_points,
        )
        self.registrations += 1
        if registration.fitness >= config.min_fitness:
            self._failures = 0
            self._motions[index] = registration
            if coverage < config.keyframe_coverage:
                self._rekey(index, clouds)
        else:  # skip the frame; after two failures in a row, suspect the keyframe and start over here
            self._failures += 1
            if self._failures >= 2:
                self._start_chain(index)

    def _rekey(self, index: int, clouds: dict[int, PartCloud]) -> None:
        """Make the frame the keyframe and register the earlier frames onto it directly (each is
        mostly a subset of the newer, larger part), newest first, starting from their motions via the
        old keyframe, or from the next newer frame's new motion when that matches _REKEY_MARGIN more
        of the frame: a motion registered onto a small old keyframe can carry a slide along a flat
        front that point-to-plane ICP cannot undo, while the newer frame is one step away on the
        larger part."""
        old = self._motions
        to_old = np.linalg.inv(old[index].motion)
        self._make_keyframe(index)
        newer = np.eye(4)
        fine = (2 * self.config.voxel_m,)
        for j in sorted(old, reverse=True):
            if j == index or j not in clouds:
                continue
            result = icp(clouds[j].source, self._keyframe, old[j].motion @ to_old, fine)
            stepped = icp(clouds[j].source, self._keyframe, newer, fine)
            if stepped.fitness > result.fitness + _REKEY_MARGIN:
                result = stepped
            self.rekey_registrations += 1
            if result.fitness >= self.config.min_fitness:
                self._motions[j] = result
                newer = result.motion


class ScrewGripEstimator(ScrewEstimator):
    """The screw estimator that also fits the held handle's path (the gripper poses from forward
    kinematics): the part's registered turns with the gripper's positions, which locate a hinge and a
    drawer's direction better than the part's sliding centroid. Without gripper poses it is `screw`."""

    name = "screw-grip"
    use_gripper = True


def held_path(held: dict[int, np.ndarray], window: Sequence[Observation]) -> dict[int, np.ndarray]:
    """The gripper's positions (frame -> position) over the hold the window ends in: `held` (the earlier frames')
    with the window's frames that have a pose added, and every frame up to the window's last one without a pose (the
    grip let go there: a re-grasp holds the handle elsewhere) dropped. The joint stays the same over a hold, and the
    held handle's path over all of it pins the hinge's tilt within the door's plate, which a window's short arc
    shows only by its sagitta."""
    released = max((o.index for o in window if o.gripper_pose is None), default=None)
    path = {i: p for i, p in held.items() if released is None or i > released}
    path.update({o.index: np.asarray(o.gripper_pose, float)[:3, 3] for o in window
                 if o.gripper_pose is not None and (released is None or o.index > released)})
    return path


def _gripper_positions(
    window: Sequence[Observation], used: list[int], held: dict[int, np.ndarray]
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The gripper's positions at the `used` frames (None unless every one has a pose), and over the hold
    (`held_path`, in frame order; None for fewer than 2)."""
    grips = {o.index: np.asarray(o.gripper_pose, float)[:3, 3] for o in window if o.gripper_pose is not None}
    at_used = np.array([grips[i] for i in used]) if all(i in grips for i in used) else None
    everywhere = np.array([held[i] for i in sorted(held)]) if len(held) >= 2 else None
    return at_used, everywhere


def open_screw(_argument: str, config: object = None) -> ScrewEstimator:
    """Registry factory of `screw`; `config` is the run's EstimatorConfig (its `screw` section is used) or None."""
    return ScrewEstimator(_screw_section(config))


def open_screw_grip(_argument: str, config: object = None) -> ScrewGripEstimator:
    """Registry factory of `screw-grip`; `config` as for `open_screw`."""
    return ScrewGripEstimator(_screw_section(config))


def _screw_section(config: object) -> ScrewConfig:
    """The `[estimator.screw]` section of an EstimatorConfig, the defaults when there is none."""
    section = getattr(config, "screw", None)
    return section if isinstance(section, ScrewConfig) else _DEFAULT_CONFIG
