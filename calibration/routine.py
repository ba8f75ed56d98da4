"""The field routine over the Camera and Arm protocols: plan stations, move, settle, detect, collect, solve.

Start with the arm where the camera sees the whole board (eye-to-hand: the board on the tool facing the
camera; eye-in-hand: the wrist camera looking at the board on the table). The routine returns the arm to
its start joints; any failure while moving stops the arm (drivers.arm.motion).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from calibration.board import BoardConfig
from calibration.check import CheckReport, check_samples, corner_in_base
from calibration.detect import BoardDetector
from calibration.hand_eye import METHODS, MIN_POSES, HandEyeSolution, Sample, Setup, calibrate, check_pose_set
from calibration.intrinsics import MIN_VIEWS, IntrinsicsResult, calibrate_intrinsics
from calibration.poses import PoseConfig, plan_stations
from calibration.store import HandEyeRecord
from drivers.arm.base import Arm
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import move_to_joints, move_to_pose
from drivers.arm.trajectory import MotionLimits
from drivers.camera.base import Camera, Intrinsics
from drivers.errors import CalibrationError

Progress = Callable[[int, int], None]
MIN_STATIONS = {"hand-eye": (MIN_POSES, 15), "intrinsics": (MIN_VIEWS, 12), "check": (2, 6)}  # (least, advised)


@dataclass(frozen=True)
class RoutineConfig:
    """What the routine does: setup, number of stations, the board, how stations are generated, the settling
    time before each image (s) and the solvers to try."""

    setup: Setup = "eye-to-hand"
    poses: int = 15
    board: BoardConfig = field(default_factory=BoardConfig)
    stations: PoseConfig = field(default_factory=PoseConfig)
    settle_s: float = 0.3
    methods: tuple[str, ...] = METHODS


@dataclass(frozen=True)
class Collection:
    """Samples where the board was found, and the stations (indices) where it was not."""

    samples: list[Sample]
    missed: list[int]
    stations: int


@dataclass(frozen=True)
class HandEyeRun:
    """The refined best solution, every solver's unrefined one, the collection it came from and the intrinsics
    and distortion the board poses were solved with."""

    best: HandEyeSolution
    solutions: list[HandEyeSolution]
    collection: Collection
    intrinsics: Intrinsics
    distortion: np.ndarray


@contextmanager
def stopping_on_error(arm: Arm) -> Iterator[None]:
    """Stop the arm if anything fails inside (a camera timeout between moves too), then re-raise."""
    try:
        yield
    except BaseException:
        arm.stop()
        raise


class Stations:
    """Moves an arm through stations and takes one board view at each; any failure stops the arm."""

    def __init__(self, camera: Camera, arm: Arm, kin: Kinematics, limits: MotionLimits, board: BoardConfig,
                 intrinsics: Intrinsics | None = None, distortion: np.ndarray | None = None,
                 settle_s: float = 0.3) -> None:
        self.camera, self.arm, self.kin, self.limits = camera, arm, kin, limits
        self.detector = BoardDetector(board)
        self.intrinsics = intrinsics or camera.intrinsics
        if intrinsics is None and distortion is None:  # the factory's intrinsics, with the factory's lens model
            distortion = self.intrinsics.dist_coeffs
        self.distortion = np.zeros(5) if distortion is None else np.asarray(distortion, float)
        self.settle_ticks = max(1, round(settle_s / arm.control_period_s))

    def look(self) -> Sample | None:
        """Hold still for the settling time, then one image and the tool pose: a Sample, None if no board."""
        with stopping_on_error(self.arm):
            return self._look()

    def _look(self) -> Sample | None:
        q = self.arm.state().q
        for _ in range(self.settle_ticks):
            self.arm.command(q, np.zeros_like(q))
            self.arm.sync()
        frame = self.camera.read()
        T_base_tool = self.kin.fk(self.arm.state().q)
        pose = self.detector.pose(frame.color, self.intrinsics, self.distortion)
        return None if pose is None else Sample(T_base_tool, pose.T_camera_board, pose.view)

    def require_board(self) -> Sample:
        sample = self.look()
        if sample is None:
            raise CalibrationError(
                f"board not visible at the start pose (no {self.detector.cfg.squares[0]}x"
                f"{self.detector.cfg.squares[1]} {self.detector.cfg.dictionary} ChArUco board found): move the arm "
                "so that the camera sees the whole board, and check the board options match the printed board"
            )
        return sample

    def collect(self, stations: list[np.ndarray], progress: Progress | None = None) -> Collection:
        """Visit every station, then return to the start joints."""
        with stopping_on_error(self.arm):
            return self._collect(stations, progress)

    def _collect(self, stations: list[np.ndarray], progress: Progress | None) -> Collection:
        q_start = self.arm.state().q
        samples, missed = [], []
        for i, q in enumerate(stations):
            move_to_joints(self.arm, q, self.limits)
            sample = self.look()
            if sample is None:
                missed.append(i)
            else:
                samples.append(sample)
            if progress is not None:
                progress(i + 1, len(stations))
        move_to_joints(self.arm, q_start, self.limits)
        return Collection(samples, missed, len(stations))


def check_poses(task: str, poses: int) -> None:
    """CalibrationError when `poses` stations are too few for `task` (a key of MIN_STATIONS): checked before the
    arm is enabled."""
    least, advised = MIN_STATIONS[task]
    if poses < least:
        raise CalibrationError(f"--poses {poses} is too few: {task} needs at least {least}, use {advised}+")


def check_pointing(record: HandEyeRecord) -> None:
    """CalibrationError when the pointing test cannot run on `record` (it needs eye-in-hand): checked before the
    arm is enabled."""
    if record.setup != "eye-in-hand":
        raise CalibrationError(f"--point is for eye-in-hand (the board is fixed), this calibration is {record.setup}:"
                               " drop --point; the check reports the camera-vs-kinematics corner error instead")


def plan_around_start(kin: Kinematics, arm: Arm, cfg: RoutineConfig) -> list[np.ndarray]:
    """`cfg.poses` station joints around the arm's current pose, inside its safety workspace."""
    workspace = (arm.limits.workspace_min, arm.limits.workspace_max)
    return plan_stations(kin, arm.state().q, cfg.poses, cfg.stations, workspace)


def run_hand_eye(camera: Camera, arm: Arm, kin: Kinematics, cfg: RoutineConfig, limits: MotionLimits,
                 intrinsics: Intrinsics | None = None, distortion: np.ndarray | None = None,
                 progress: Progress | None = None) -> HandEyeRun:
    """The hand-eye routine: board check at the start pose, `cfg.poses` stations, every solver, the most
    consistent refined. Raises CalibrationError when the board is not seen or the poses are degenerate."""
    check_poses("hand-eye", cfg.poses)
    stations = Stations(camera, arm, kin, limits, cfg.board, intrinsics, distortion, cfg.settle_s)
    stations.require_board()
    collection = stations.collect(plan_around_start(kin, arm, cfg), progress)
    found = len(collection.samples)
    if found < MIN_POSES or found < cfg.poses // 2:
        raise CalibrationError(
            f"board detected at only {found} of {collection.stations} poses: keep it in view (smaller tilts, "
            "--pivot at the board centre), light it evenly and avoid glare"
        )
    check_pose_set(cfg.setup, [s.T_base_tool for s in collection.samples])
    best, solutions = calibrate(collection.samples, cfg.setup, stations.intrinsics.K, stations.distortion,
                                cfg.methods)
    return HandEyeRun(best, solutions, collection, stations.intrinsics, stations.distortion)


def run_intrinsics(camera: Camera, arm: Arm, kin: Kinematics, cfg: RoutineConfig, limits: MotionLimits,
                   progress: Progress | None = None) -> IntrinsicsResult:
    """Intrinsics from board views at `cfg.poses` stations, seeded with the camera's factory values."""
    check_poses("intrinsics", cfg.poses)
    stations = Stations(camera, arm, kin, limits, cfg.board, settle_s=cfg.settle_s)
    stations.require_board()
    collection = stations.collect(plan_around_start(kin, arm, cfg), progress)
    factory = camera.intrinsics
    return calibrate_intrinsics([s.view for s in collection.samples], factory.width, factory.height, factory)


@dataclass(frozen=True)
class PointResult:
    """The pointing test, base frame (m): the board's centre corner as the camera sees it through the
    calibration, where the tool tip was sent (hover_m in front of it) and where forward kinematics says it went."""

    corner: np.ndarray
    target: np.ndarray
    reached: np.ndarray
    hover_m: float


def run_check(camera: Camera, arm: Arm, kin: Kinematics, record: HandEyeRecord, cfg: RoutineConfig,
              limits: MotionLimits, camera_serial: str, max_age_days: float = 30.0,
              progress: Progress | None = None) -> CheckReport:
    """Fresh samples at `cfg.poses` stations evaluated with the stored calibration and the camera's factory
    intrinsics (calibration.check)."""
    check_poses("check", cfg.poses)
    stations = Stations(camera, arm, kin, limits, record.board, record.intrinsics, record.distortion, cfg.settle_s)
    stations.require_board()
    collection = stations.collect(plan_around_start(kin, arm, cfg), progress)
    if len(collection.samples) < MIN_STATIONS["check"][0]:
        raise CalibrationError(f"board detected at only {len(collection.samples)} of {collection.stations} "
                                   "check poses: keep it in view")
    return check_samples(record, collection.samples, camera_serial, max_age_days, camera.intrinsics)


def point_at_board(camera: Camera, arm: Arm, kin: Kinematics, record: HandEyeRecord, limits: MotionLimits,
                   hover_m: float = 0.02, settle_s: float = 0.3) -> PointResult:
    """Eye-in-hand one-shot test: move the tool tip to `hover_m` in front of the board's centre corner, keeping
    its orientation, so the user can see the gap; then back to the start. Needs the fixed board in view."""
    check_pointing(record)
    stations = Stations(camera, arm, kin, limits, record.board, record.intrinsics, record.distortion, settle_s)
    sample = stations.require_board()
    corner = corner_in_base(record, sample)
    towards_camera = -(record.T_base_camera(sample.T_base_tool) @ sample.T_camera_board)[:3, 2]
    target = sample.T_base_tool.copy()
    target[:3, 3] = corner + hover_m * towards_camera
    with stopping_on_error(arm):
        q_start = arm.state().q
        move_to_pose(arm, kin, target, limits)
        stations.look()  # settle
        reached = kin.fk(arm.state().q)[:3, 3]
        move_to_joints(arm, q_start, limits)
    return PointResult(corner, target[:3, 3], reached, hover_m)
