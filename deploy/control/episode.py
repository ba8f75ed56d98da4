"""One opening episode on any camera and arm: perceive, grasp, first pull, then axis-guided steps.

The policy sees only camera frames and the arm (measured joints, forward kinematics); progress is the
gripper's travel along / about the estimated axis since the grasp. Frames are grabbed during motions
(every 1/camera_hz of arm time) and processed between motions.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.axis_pipeline import AxisPipeline, frame_points, viewpoint
from deploy.config import Config, EstimatorConfig
from deploy.control.classify import classify_joint, front_shift_m, front_turn_deg
from deploy.control.grasp import (
    REGRASP_RADIUS_M,
    Handle,
    find_handle,
    grasp_pose,
    hinge_prior,
    pregrasp_configuration,
    pregrasp_pose,
    protruding_points,
)
from deploy.control.policy import OpenConfig, choose_axis, opening, orient_axis, seen_opening
from deploy.control.run_folder import RunFolder
from deploy.control.viewer import RerunViewer
from deploy.errors import PerceptionError
from deploy.geometry.estimators.trajectory import fit_trajectory
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis
from deploy.perception.base import Segmenter
from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import (
    PathFn,
    PathResult,
    arc_path,
    follow_cartesian_path,
    line_path,
    move_to_joints,
    move_to_pose,
)
from drivers.arm.robots import panda
from drivers.arm.trajectory import MotionLimits
from drivers.camera.base import Camera, Frame
from drivers.errors import ArmError

GRIPPER_FORCE_N = 40.0
CLOSE_TIME_S = 0.5
MIN_GRASP_WIDTH_M = 0.003  # a closed gripper narrower than this holds nothing
OPEN_MARGIN_M = 0.005  # a gripper within this of fully open did not close on anything
MAX_DRAWER_LAG_M = 0.03  # how far a drawer may lag the gripper's travel (a stretched grasp)
OVERSHOOT = {JointType.PRISMATIC: 0.015, JointType.REVOLUTE: float(np.radians(5.0))}  # past the target
SETTLE_S = 0.3  # after a motion the arm settles on its last command (a new motion starts from the
# measured joints, and the safety layer refuses a jump from the last command to them)
RETREAT_M = 0.05  # re-grasp: back off this far along the approach and come back
AxisError = Callable[[Axis], tuple[float, float]]


@dataclass
class EpisodeResult:
    """How an episode ended. opened / target: m (drawer) or deg (door); stop_reason: a short category
    ("target reached", "blocked", "grasp lost", ...) and `message` the details."""

    success: bool
    opened: float
    target: float
    steps: int
    joint_type: str | None
    axis: Axis | None
    stop_reason: str
    message: str
    run_dir: Path | None
    timings: dict[str, float]
    regrasped: bool = False
    estimates: list[dict] = field(default_factory=list)
    commanded: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    measured: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    opening_curve: list[tuple[float, float]] = field(default_factory=list)

    def to_dict(self) -> dict:
        """The JSON result of `deploy open --json`."""
        axis = None if self.axis is None else {
            k: v for k, v in self.axis.to_dict().items() if k in ("joint_type", "origin", "direction")}
        return {"success": self.success, "opened": self.opened, "target": self.target, "steps": self.steps,
                "axis": axis, "stop_reason": self.stop_reason, "message": self.message, "regrasped": self.regrasped,
                "run_dir": None if self.run_dir is None else str(self.run_dir), "timings": self.timings}


class _Stop(Exception):
    """Ends the episode with a stop category and a message."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason, self.message = reason, message


def run_episode(
    camera: Camera,
    arm: Arm,
    kin: Kinematics,
    segmenter: Segmenter,
    config: OpenConfig,
    run_dir: str | Path | None = None,
    joint_limits: MotionLimits | None = None,
    axis_error: AxisError | None = None,
    viewer: RerunViewer | None = None,
) -> EpisodeResult:
    """Open the object in view to `config`'s target; always leaves the arm stopped.

    joint_limits: free-space joint moves (default 0.3 of the Panda's limits). axis_error: EVALUATION
    only (simulation truth), drawn in the run folder's report; never used for control. viewer: `--view`.
    """
    episode = _Episode(camera, arm, kin, segmenter, config, joint_limits)
    folder = RunFolder(Path(run_dir)) if run_dir is not None else None
    episode.folder, episode.viewer = folder, viewer
    try:
        reason, message = episode.run()
    except _Stop as stop:
        reason, message = stop.reason, stop.message
    except ArmError as exc:
        reason, message = ("ik infeasible" if _is_ik(exc) else "arm error"), str(exc)
    except PerceptionError as exc:  # the segmenter lost the object and could not find it again
        reason, message = "tracking lost", str(exc)
    finally:
        arm.stop()
        if viewer is not None:
            viewer.close()
    result = episode.result(reason, message, folder)
    if folder is not None:
        folder.finish(result, episode.first_frame, axis_error)
    return result


def _is_ik(exc: ArmError) -> bool:
    text = str(exc)
    return text.startswith(("ik:", "path waypoint", "target pose unreachable")) or "out of reach" in text


class _Episode:
    def __init__(self, camera: Camera, arm: Arm, kin: Kinematics, segmenter: Segmenter, config: OpenConfig,
                 joint_limits: MotionLimits | None) -> None:
        self.camera, self.arm, self.kin, self.segmenter, self.config = camera, arm, kin, segmenter, config
        self.joint_limits = joint_limits or MotionLimits.for_robot(panda(), kin, 0.3)
        estimator = "paper-obb" if config.policy == "paper" else config.estimator
        self.joint = {"drawer": JointType.PRISMATIC, "door": JointType.REVOLUTE}.get(config.task)
        self.pipeline = AxisPipeline(Config(estimator=EstimatorConfig(
            name=estimator, joint="auto" if self.joint is None else self.joint.value, window=config.window)))
        self.folder: RunFolder | None = None
        self.viewer: RerunViewer | None = None
        self.first_frame: Frame | None = None
        self.last_seen: tuple[Frame, np.ndarray] | None = None  # the latest processed frame and its mask
        self.first_points = np.zeros((0, 3))
        self.mask_pixels = 0
        self.pending: list[tuple[Frame, ArmState]] = []
        self.next_frame_t = 0.0
        self.vision: AxisResult = NoAxis("no frames yet")
        self.axis: Axis | None = None
        self.opened = 0.0
        self.steps = 0
        self.estimates: list[dict] = []
        self.commanded: list[np.ndarray] = []
        self.measured: list[np.ndarray] = []
        self.curve: list[tuple[float, float]] = []
        self.timings: dict[str, float] = {"perceive_s": 0.0, "grasp_s": 0.0, "motion_s": 0.0, "estimate_s": 0.0}
        self.t0 = arm.time()
        self.p_grasp = np.zeros(3)  # where the opening is measured from (the grasp, or after a door's probe)
        self.opened_before = 0.0  # opening before p_grasp (m or rad)
        self.open_width = 0.0
        self.regrasped = False
        self.estimated = False  # an estimate (not a prior) has been acted on

    # --- stages -----------------------------------------------------------------------------------------

    def run(self) -> tuple[str, str]:
        cfg = self.config
        handle = self.perceive()
        if cfg.dry_run:
            return self.plan(handle)
        self.grasp(handle)
        pull = handle.normal
        if self.joint is None:  # `--joint auto`: a short straight pull, then drawer or door from the front
            self.pull(line_path(self.tool(), pull), cfg.probe_pull_m, "probe pull")
            self.classify(handle)
        if self.joint is JointType.REVOLUTE:
            self.axis = hinge_prior(handle, self.first_points, self.pipeline.body_box)
        if self.joint is JointType.REVOLUTE and cfg.policy != "paper":  # a small arc about the likely hinge
            radius = max(float(np.linalg.norm(np.cross(self.axis.direction, self.p_grasp - self.axis.origin))), 0.1)
            self.pull(arc_path(self.tool(), self.axis.origin, self.axis.direction), cfg.first_pull_m / radius,
                      "first pull", self.arc_limits())
        else:
            self.pull(line_path(self.tool(), pull), cfg.first_pull_m, "first pull")
        while True:
            axis, source = self.estimate(pull)
            if self.opened >= self.target():
                return "target reached", f"opened {self.report_opened():.3f} of {self.report_target():.3f}"
            if self.steps >= cfg.max_steps:
                raise _Stop("max steps", f"{cfg.max_steps} steps made, opened {self.report_opened():.3f}")
            if self.arm.time() - self.t0 > cfg.timeout_s:
                raise _Stop("timeout", f"{cfg.timeout_s:.0f} s of arm time used, opened {self.report_opened():.3f}")
            path, length, limits = self.step_path(axis)
            self.pull(path, length, f"step {self.steps}: {source}", limits)

    def perceive(self) -> Handle:
        clock = time.perf_counter()
        frame = self.camera.read()
        self.first_frame = frame
        mask = self.segmenter.start(frame)
        self.mask_pixels = int(np.count_nonzero(mask))
        if self.mask_pixels == 0:
            raise _Stop("no object", "the segmenter found no object on the first frame: point the camera at it")
        state = self.arm.state()
        self.pipeline.update_frame(frame, mask, self.kin.fk(state.q))
        if self.folder is not None:
            self.folder.write_frame(frame, mask, state.q, self.kin.fk(state.q))
        handle_mask = self.segmenter.handle_mask(frame)
        points = (self.pipeline.handle_points if handle_mask is None
                  else frame_points(frame, handle_mask, self.pipeline.config))
        box = self.pipeline.body_box
        self.first_points = frame_points(frame, mask, self.pipeline.config)
        if self.viewer is not None:
            self.viewer.cloud(self.first_points)
            self.viewer.frame(0.0, frame, mask, self.kin.fk(state.q))
        handle = None if box is None else find_handle(
            points, self.first_points, box, viewpoint(frame), self.joint is JointType.REVOLUTE)
        self.timings["perceive_s"] += time.perf_counter() - clock
        if handle is None:
            raise _Stop("no handle", "no handle found on the first frame (too few points protrude from the "
                        "front): check the camera view and the mask")
        self.next_frame_t = self.arm.time()
        return handle

    def plan(self, handle: Handle) -> tuple[str, str]:
        """`--dry-run`: the grasp, approach and first pull planned and checked by IK, nothing commanded."""
        cfg, kin = self.config, self.kin
        T_grasp = grasp_pose(handle)
        q_pre = pregrasp_configuration(kin, self.arm.state().q, T_grasp, self.planned_reach() * handle.normal,
                                       cfg.approach_m)
        self.axis = (hinge_prior(handle, self.first_points, self.pipeline.body_box)
                     if self.joint is JointType.REVOLUTE else Axis(JointType.PRISMATIC, handle.center, handle.normal,
                                                                   confidence=0.0))
        T_pre = kin.fk(q_pre)
        self.commanded.extend([T_pre, T_grasp])
        self.estimates.append({"step": 0, "t": 0.0, "source": "plan (prior)", "axis": self.axis.to_dict(),
                               "opened": 0.0, "vision": "dry run"})
        p = T_grasp[:3, 3]
        return "dry run", (f"planned: handle at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m, pre-grasp joints "
                           f"{np.round(q_pre, 3).tolist()}, {self.joint_type().value} prior axis; nothing moved")

    def planned_reach(self) -> float:
        """How far the pre-grasp configuration must be able to pull straight (m)."""
        if self.joint is JointType.REVOLUTE:
            return 0.1
        return self.config.target_distance_m + OVERSHOOT[JointType.PRISMATIC]

    def classify(self, handle: Handle) -> None:
        """Drawer or door from how the front turned during the probe pull; fixes the estimator's joint."""
        if self.last_seen is None:
            raise _Stop("tracking lost", "no frame was seen during the probe pull: check the camera")
        frame, mask = self.last_seen
        after = frame_points(frame, mask, self.pipeline.config)
        turn = front_turn_deg(handle.normal, after, self.tool()[:3, 3], self.pipeline.body_box, viewpoint(frame))
        shift = front_shift_m(self.first_points, after, handle.center, handle.normal)
        self.joint = classify_joint(turn, shift, self.config.probe_pull_m)
        self.pipeline.joint = self.joint
        if self.joint is JointType.REVOLUTE:  # the straight probe slips on a door's arc: count the turn seen
            self.p_grasp, self.opened_before = self.tool()[:3, 3], float(np.radians(turn))
        self.estimates.append({"step": 0, "t": self.arm.time() - self.t0, "source": "probe pull", "axis": None,
                               "classified": self.joint.value, "front_turn_deg": turn, "front_shift_m": shift})

    def grasp(self, handle: Handle) -> None:
        clock = time.perf_counter()
        cfg, arm, kin = self.config, self.arm, self.kin
        T_grasp = grasp_pose(handle)
        q_pre = pregrasp_configuration(kin, arm.state().q, T_grasp, self.planned_reach() * handle.normal,
                                       cfg.approach_m)
        arm.set_gripper(1.0)  # fully open (clipped to the gripper's width)
        move_to_joints(arm, q_pre, self.joint_limits)
        open_width = arm.state().gripper_width_m
        T = self.tool()
        follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), cfg.approach_m, self.line_limits())
        self.close_and_check(open_width, "grasp failed")
        self.open_width = open_width
        self.p_grasp = self.tool()[:3, 3]
        self.timings["grasp_s"] += time.perf_counter() - clock

    def close_and_check(self, open_width: float, failure: str, context: str = "") -> None:
        self.arm.set_gripper(0.0, GRIPPER_FORCE_N)
        self.wait(CLOSE_TIME_S)
        width = self.arm.state().gripper_width_m
        if not MIN_GRASP_WIDTH_M < width < open_width - OPEN_MARGIN_M:
            raise _Stop(failure, f"{context}gripper closed to {width * 1e3:.1f} mm (open {open_width * 1e3:.1f} mm): "
                        "it missed the handle; check the handle detection and the camera calibration")

    def regrasp(self) -> None:
        """Open, back off along the approach, find the handle again in a fresh frame near where it was held,
        approach it and close. The opening measured before the slipping pull is kept (the slipping pull's
        share is not counted: the arm errs toward opening further); later travel counts from the new grip."""
        arm, kin = self.arm, self.kin
        held = self.tool()[:3, 3]
        arm.set_gripper(self.open_width)
        self.wait(CLOSE_TIME_S)
        T = self.tool()
        follow_cartesian_path(arm, kin, line_path(T, -T[:3, 2]), RETREAT_M, self.line_limits())
        frame = self.camera.read()
        points = frame_points(frame, self.segmenter.track(frame), self.pipeline.config)
        handle = find_handle(protruding_points(points, held, viewpoint(frame)), points, self.pipeline.body_box,
                             viewpoint(frame), self.joint_type() is JointType.REVOLUTE)
        if handle is None:
            raise _Stop("grasp lost", f"the handle slipped out of the gripper and was not found again within "
                        f"{REGRASP_RADIUS_M * 100:.0f} cm of where it was held: check the view of the handle")
        T_grasp = grasp_pose(handle)
        move_to_pose(arm, kin, pregrasp_pose(T_grasp, RETREAT_M), self.joint_limits)
        self.wait(SETTLE_S)
        T = self.tool()
        follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), RETREAT_M, self.line_limits())
        self.close_and_check(self.open_width, "grasp lost", "re-grasp after a slip failed: ")
        self.opened_before, self.p_grasp = self.opened, self.tool()[:3, 3]

    def step_path(self, axis: Axis) -> tuple[PathFn, float, MotionLimits]:
        """The next step: a line (drawer, or the paper's straight steps) or an arc about the axis (door)."""
        cfg = self.config
        remaining = self.target() - self.opened + OVERSHOOT[axis.joint_type]
        step = cfg.step_for(axis.joint_type, self.steps)
        T = self.tool()
        if cfg.policy == "paper":  # straight lines along the line or the arc's tangent, in metres
            if axis.joint_type is JointType.PRISMATIC:
                direction, length = axis.direction, min(step, remaining)
            else:
                direction = np.cross(axis.direction, T[:3, 3] - axis.origin)
                radius = max(float(np.linalg.norm(direction)), 0.05)
                length = min(step, remaining * radius)
            return line_path(T, direction), length, self.line_limits()
        if axis.joint_type is JointType.PRISMATIC:
            return line_path(T, axis.direction), min(step, remaining), self.line_limits()
        return arc_path(T, axis.origin, axis.direction), min(step, remaining), self.arc_limits()

    # --- motion and perception --------------------------------------------------------------------------

    def pull(self, path: PathFn, length: float, label: str, limits: MotionLimits | None = None) -> None:
        """One motion with frames grabbed on the way, then the frames through the pipeline and the checks."""
        clock = time.perf_counter()

        def on_tick(state: ArmState, _t: float) -> bool:
            self.capture(state)
            return state.gripper_width_m > MIN_GRASP_WIDTH_M

        self.arm.set_compliance(True)
        try:
            result = follow_cartesian_path(self.arm, self.kin, path, max(length, 1e-4),
                                           limits or self.line_limits(), on_tick)
            self.wait(SETTLE_S)
        finally:
            self.arm.set_compliance(False)
        self.next_frame_t = 0.0
        self.capture(self.arm.state())  # the settled end of the motion
        self.timings["motion_s"] += time.perf_counter() - clock
        self.steps += label.startswith("step")
        self.record(result, label)
        self.process_frames()
        if self.arm.state().gripper_width_m <= MIN_GRASP_WIDTH_M:
            if self.regrasped:
                raise _Stop("grasp lost", f"the handle slipped out of the gripper again during {label}, "
                            "after one re-grasp: the pull needs more force than the grasp holds")
            self.regrasped = True
            self.regrasp()
        elif result.reason.startswith("blocked"):
            raise _Stop("blocked", f"no more motion during {label} ({result.reason}): the joint is at its "
                        "limit or locked")

    def capture(self, state: ArmState) -> None:
        if state.t + 1e-9 >= self.next_frame_t:
            self.pending.append((self.camera.read(), state))
            self.next_frame_t = state.t + 1.0 / self.config.camera_hz

    def process_frames(self) -> None:
        clock = time.perf_counter()
        for frame, state in self.pending:
            mask = self.segmenter.track(frame)
            pose = self.kin.fk(state.q)
            if self.folder is not None:
                self.folder.write_frame(frame, mask, state.q, pose)
            if self.viewer is not None:
                self.viewer.frame(state.t - self.t0, frame, mask, pose)
            if np.count_nonzero(mask) < self.config.min_mask_fraction * self.mask_pixels:
                self.pending = []
                raise _Stop("tracking lost", f"the object's mask shrank to {np.count_nonzero(mask)} pixels of "
                            f"{self.mask_pixels} at frame {frame.index}: the object left the view or is occluded")
            self.vision = self.pipeline.update_frame(frame, mask, pose).result
            self.last_seen = frame, mask
        self.pending = []
        self.timings["estimate_s"] += time.perf_counter() - clock

    def estimate(self, pull: np.ndarray) -> tuple[Axis, str]:
        """The axis to act on, updating the opening; the open-loop policy keeps its first estimate.

        Before any usable estimate: the door's hinge prior, or a line along the front normal."""
        clock = time.perf_counter()
        p_now = self.tool()[:3, 3]
        if self.estimated and self.config.policy == "open":
            chosen, source = self.axis, "fixed"
        else:
            poses = np.array(self.measured)
            joint = self.joint or (self.vision.joint_type if isinstance(self.vision, Axis) else None)
            trajectory = fit_trajectory(poses[:, :3, 3], Rotation.from_matrix(poses[:, :3, :3]).as_quat(), joint)
            moved = self.opened if self.axis is None or self.axis.joint_type is JointType.PRISMATIC \
                else float(np.degrees(self.opened))
            result, source = choose_axis(self.vision, trajectory, self.joint, moved, self.config)
            chosen = orient_axis(result, self.measured_pull(pull), self.p_grasp) if isinstance(result, Axis) else None
            self.estimated |= chosen is not None
            if chosen is None:
                chosen = self.axis if self.axis is not None else Axis(JointType.PRISMATIC, self.p_grasp, pull,
                                                                      confidence=0.0)
                source = f"prior ({source})"
        self.axis = chosen
        self.opened = self.opened_before + opening(chosen, self.p_grasp, p_now)
        if chosen.joint_type is JointType.PRISMATIC and self.pipeline.window:
            # A drawer lags a stretched grasp: trust the camera's reading when it is a little short of the
            # gripper's (more than MAX_DRAWER_LAG_M short is a misreading, not a lag).
            seen = seen_opening(self.pipeline.window[-1].moving, self.first_points, chosen.direction)
            if seen is not None and self.opened - MAX_DRAWER_LAG_M <= seen < self.opened:
                self.opened = seen
        self.curve.append((self.arm.time() - self.t0, self.report_opened()))
        if self.viewer is not None:
            self.viewer.axis(self.arm.time() - self.t0, chosen, self.report_opened())
        self.estimates.append({"step": self.steps, "t": self.arm.time() - self.t0, "source": source,
                               "axis": chosen.to_dict(),
                               "opened": self.report_opened(),
                               "vision": self.vision.reason if isinstance(self.vision, NoAxis)
                               else f"{self.vision.joint_type.value}, confidence {self.vision.confidence:.3f}"})
        self.timings["estimate_s"] += time.perf_counter() - clock
        return chosen, source

    def measured_pull(self, pull: np.ndarray) -> np.ndarray:
        """The direction the grip point actually moved since the grasp, or the front normal before that."""
        moved = self.tool()[:3, 3] - self.p_grasp
        return moved if np.linalg.norm(moved) > 0.01 else pull

    def record(self, result: PathResult, label: str) -> None:
        self.commanded.extend(result.planned)
        self.measured.extend(result.measured)
        if self.folder is not None:
            self.folder.add_motion(label, result)

    # --- helpers ----------------------------------------------------------------------------------------

    def tool(self) -> np.ndarray:
        return self.kin.fk(self.arm.state().q)

    def wait(self, duration_s: float) -> None:
        """Hold the last command for `duration_s` of arm time."""
        for _ in range(int(round(duration_s / self.arm.control_period_s))):
            self.arm.sync()

    def line_limits(self) -> MotionLimits:
        v = self.config.pull_speed_m_s
        return MotionLimits(v, 4 * v, 40 * v)

    def arc_limits(self) -> MotionLimits:
        v = float(np.radians(self.config.pull_speed_deg_s))
        return MotionLimits(v, 4 * v, 40 * v)

    def joint_type(self) -> JointType:
        return self.joint or (self.axis.joint_type if self.axis is not None else JointType.PRISMATIC)

    def target(self) -> float:
        return self.config.target_for(self.joint_type())

    def _scale(self) -> float:
        return float(np.degrees(1.0)) if self.joint_type() is JointType.REVOLUTE else 1.0

    def report_opened(self) -> float:
        return self.opened * self._scale()

    def report_target(self) -> float:
        return self.target() * self._scale()

    def result(self, reason: str, message: str, folder: RunFolder | None) -> EpisodeResult:
        self.timings["sim_time_s"] = self.arm.time() - self.t0
        return EpisodeResult(
            success=self.axis is not None and self.opened >= self.target(), opened=self.report_opened(),
            target=self.report_target(), steps=self.steps,
            joint_type=None if self.axis is None else self.axis.joint_type.value, axis=self.axis,
            stop_reason=reason, message=message, run_dir=None if folder is None else folder.path,
            timings=self.timings, regrasped=self.regrasped, estimates=self.estimates,
            commanded=np.array(self.commanded).reshape(-1, 4, 4), measured=np.array(self.measured).reshape(-1, 4, 4),
            opening_curve=self.curve,
        )
