"""The stages of an opening episode, in order; each reads and updates `episode.state` (SI units) and ends the
episode by raising `EpisodeStop` with a `StopReason`."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.axis_pipeline import viewpoint
from deploy.control.classify import classify_joint, front_shift_m, front_turn_deg
from deploy.control.context import MIN_GRASP_WIDTH_M, SETTLE_S, Episode
from deploy.control.door_regrasp import closing_push_n, door_plane, held_as, held_centre, opening_direction
from deploy.control.grasp import (
    REGRASP_RADIUS_M,
    Handle,
    back_along_path,
    find_handle,
    front_normal,
    grasp_pose,
    hinge_prior,
    hinge_side,
    hinge_side_sure,
    pointed_handle,
    pregrasp_configuration,
    pregrasp_pose,
    protruding_points,
    pull_poses,
)
from deploy.control.policy import choose_axis, hinge_from_turn, opening, orient_axis, seen_opening
from deploy.control.scene_clearance import Scene, clear_grasps, scene_tree
from deploy.control.state import EpisodeStop, StopReason, display_scale, opening_unit
from deploy.control.view import step_log
from deploy.errors import PartHiddenError, PointerError
from deploy.geometry.cloud import depth_to_points, points_to_pixels
from deploy.geometry.estimators.trajectory import fit_trajectory
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis
from deploy.perception.base import Pointer
from deploy.perception.pointing import point_at
from drivers.arm.base import ArmState
from drivers.arm.grasping import GRASP_PITCH_RAD
from drivers.arm.motion import (
    Outcome,
    PathFn,
    arc_path,
    follow_cartesian_path,
    line_path,
    move_to_joints,
    move_to_pose,
)
from drivers.arm.trajectory import MotionLimits
from drivers.arm.wrench import WrenchEstimator, torque_offset
from drivers.camera.base import Frame
from drivers.errors import IKError

log = logging.getLogger(__name__)

CLOSE_TIME_S = 0.5
OPEN_MARGIN_M = 0.005  # a gripper within this of fully open did not close on anything
MAX_DRAWER_LAG_M = 0.03  # how far a drawer may lag the gripper's travel (a stretched grasp)
OVERSHOOT = {JointType.PRISMATIC: 0.015, JointType.REVOLUTE: float(np.radians(5.0))}  # steps aim this far past
# the target, so that an opening measured a little long still leaves the object open to the target
GOAL_TOLERANCE = {JointType.PRISMATIC: 0.005, JointType.REVOLUTE: float(np.radians(1.0))}  # the goal is reached
# this close to it
RETREAT_M = 0.05  # re-grasp: back off this far along the approach and come back
ARM_TOUCH_PX = 100  # the arm's pixels touching the object's on the first frame: it may hide the handle
CLEAR_VIEW_TURNS_RAD = (0.7, -0.7, 1.2, -1.2)  # first-joint swings tried to take the arm out of the view
MIN_DOOR_RADIUS_M = 0.1  # the first arc's radius is taken as at least this
MIN_SEEN_TURN_DEG = 5.0  # a door's front seen turned less than this does not place its hinge (`hinge_from_turn`)
PLANNED_DOOR_ARCS_DEG = (45.0, 30.0, 15.0)  # a door's pre-grasp is planned for the longest of these arcs it carries
PLANNED_DOOR_REACH_M = 0.1  # ... or else for this much straight pull
MIN_PLANNED_PULL_M = 0.05  # straight pulls planned are halved down to this
HINGE_ALIGNED_COS = float(np.cos(np.radians(20.0)))  # fingers closing within 20 deg of the hinge close "along" it:
# the door turning between the pads twists the handle in them by at most a third of its turn (sin 20 deg)
TURNING_HANDLES = ("edge pull", "cup", "bar")  # handles that may turn between the pads about the fingers' closing
PLANNED_LINE_STEP_M, PLANNED_ARC_STEP_RAD = 0.05, float(np.radians(5.0))  # planned pulls are checked this finely
ONE_FINGER_SHARE = 0.5  # closed, the arm feels more than this share of the grip force across the fingers: one finger
# alone presses the handle
CENTRING_STEP_M = 0.002  # such a handle is centred between the fingers in steps of this
REST_READING_S = 0.1  # a force at rest is the mean of the readings over this long
PRESS_N = 10.0  # the approach ended with the tool pushing the handle this hard: ease back before closing
EASE_STEP_M, MAX_EASE_M = 0.004, 0.02  # easing back: step, and at most this far
DOOR_REGRASP_YAWS_DEG = (45.0, 30.0, 15.0)  # a door's arc out of reach: its handle is held again with the hand
# turned back toward the robot by the first of these (at most the door's turn so far) that keeps clear of the scene
# and of the door and that the arm carries
MAX_TURNED_REGRASPS = 2
MAX_PRIOR_BLOCKS = 1  # a door's step blocked across its arc about the hinge prior goes on this often
SELF_CLOSING_PROBE_RAD = float(np.radians(3.0))  # before letting a door go, the hand eases it this far back toward
# closed and carries it open again, feeling whether it pushes toward closed by itself
SELF_CLOSING_N = 2.0  # a door pushing its handle toward closed harder than this (four times the wrench's noise at
# rest) is self-closing: let go, it swings shut
HELD_SWING_SPEED_SHARE = 0.25  # the door's probe and a swing about a held handle move at this share of the arc's
# speed: the arm's own inertia stays out of the force felt, and the admittance keeps up with a pivot off the grip
SAME_GRASP_M, SAME_GRASP_RAD = 0.02, GRASP_PITCH_RAD / 2  # a grasp this near one the scene clearance passed is
# that one (half the turn between its tilted and level grasps)
MAX_RESEATS = 2  # a drawer's pull out of the arm's reach: the arm takes the handle again from another configuration
# at most this often
FOLLOW_CHECK_M = 0.1  # a drawer carried this far has left its place where the user pointed (depth noise at 1.5 m is
# a third of it)


def run(episode: Episode, dry_run: bool = False) -> tuple[StopReason, str]:
    """All stages; returns how the episode ended when it did not stop early (EpisodeStop)."""
    handle = perceive(episode, dry_run)
    if dry_run:
        return plan(episode, handle)
    grasp(episode, handle)
    if episode.state.joint is None:  # `--joint auto`
        probe_and_classify(episode, handle)
    first_pull(episode, handle)
    while True:
        axis, source = estimate(episode, handle.normal)
        _check_followed(episode, axis)
        if episode.state.opened >= _goal(episode, axis) - GOAL_TOLERANCE[axis.joint_type]:
            return StopReason.TARGET_REACHED, f"opened {_shown(episode, episode.state.opened):.3f} of " \
                                              f"{_shown(episode, episode.target()):.3f}"
        step(episode, axis, source)


def perceive(episode: Episode, dry_run: bool = False) -> Handle:
    """The first frame: the object's mask and body box, the handle (the pointed front's when the user pointed; else
    its own mask when the segmenter tells it apart, else the points protruding from the front). When the arm hides
    the handle or the pointed part, or touches the object in the image, it swings out of the view first and the
    camera looks again (a dry run only says so, and stops with the pointer's line when the arm hides the part)."""
    clock = time.perf_counter()
    hidden = None
    try:
        handle = _find_handle(episode)
    except PartHiddenError as e:  # the arm hides the pointed part
        handle, hidden = None, e
    clear = _clear_view(episode) if handle is None or _arm_in_the_way(episode) else None
    if clear is not None and dry_run:
        log.info("dry run: the arm hides part of the object; a run would first turn %s to %.2f rad and look again",
                 episode.kin.joint_names[0], clear[0])
    elif clear is not None:
        move_to_joints(episode.arm, clear, episode.joint_limits)
        episode.wait(SETTLE_S)
        handle, hidden = _find_handle(episode, again=True), None
    if hidden is not None:
        raise EpisodeStop(StopReason.POINTER_REFUSED, str(hidden))
    episode.state.timings["perceive_s"] += time.perf_counter() - clock
    if handle is None:
        raise EpisodeStop(StopReason.NO_HANDLE, "no handle found on the first frame (too few points protrude "
                          "from the front): check the camera view and the mask")
    episode.state.handle = handle
    how = f"{handle.points} {handle.found}" if handle.points else f"a {handle.found} on the pointed front"
    log.info("handle found: centre %s m, front normal %s, bar %s (%s)", _vec(handle.center), _vec(handle.normal),
             _vec(handle.bar), how)
    return handle


def _vec(v: np.ndarray) -> str:
    return str(np.round(np.asarray(v, float), 3).tolist())


def _find_handle(episode: Episode, again: bool = False) -> Handle | None:
    """The first frame's handle: the pointed front's when the user pointed (EpisodeStop with the pointer's line
    when it shows none that the gripper can hold; PartHiddenError when the arm hides it, unless looking `again`),
    else the points protruding from the body box's front."""
    observer, arm = episode.observer, episode.arm
    try:
        look = observer.first(arm.state, arm.commanded_q, episode.gripper)
    except PointerError as refused:
        if isinstance(refused, PartHiddenError) and not again:
            raise
        raise EpisodeStop(StopReason.POINTER_REFUSED, str(refused)) from None
    pointed = observer.pointed
    if pointed is not None:
        if pointed.handle.graspability <= 0.0:
            raise EpisodeStop(StopReason.NO_HANDLE, f"the pointed front's {pointed.handle.kind} cannot be held: "
                              f"{pointed.handle.reason}; point at a part with another handle")
        return pointed_handle(pointed.handle, episode.state.joint is JointType.REVOLUTE)
    points = observer.handle_points()
    return None if look.body_box is None else find_handle(
        points, look.points, look.body_box, viewpoint(look.frame), episode.state.joint is JointType.REVOLUTE)


def _arm_in_the_way(episode: Episode) -> bool:
    """Whether the arm's pixels touch the object's on the first frame (it may hide part of the front)."""
    return episode.observer.arm_near_object() > ARM_TOUCH_PX


def _clear_view(episode: Episode) -> np.ndarray | None:
    """The joints with the first joint (the base's turn) swung so that the arm hides the least of the object,
    within the arm's joint limits, if that is less than now; None when there is nothing better (or no
    self-filter to tell)."""
    observer, arm = episode.observer, episode.arm
    state = arm.state()
    if observer.arm_hiding(state.q, state.gripper_width_m) is None:
        return None

    def hidden(q: np.ndarray) -> int:
        return observer.arm_hiding(q, state.gripper_width_m)

    q_min, q_max = arm.limits.q_min, arm.limits.q_max
    candidates = [state.q + np.eye(len(state.q))[0] * turn for turn in CLEAR_VIEW_TURNS_RAD]
    candidates = [q for q in candidates if q_min[0] + 0.1 <= q[0] <= q_max[0] - 0.1]
    best = min(candidates, key=hidden, default=None)
    return None if best is None or hidden(best) >= hidden(state.q) else best


def plan(episode: Episode, handle: Handle) -> tuple[StopReason, str]:
    """`--dry-run`: the grasp, approach and first pull planned and checked by IK, nothing commanded."""
    state, kin = episode.state, episode.kin
    T_grasp, _, q_pre = _grasp_plan(episode, handle)
    state.axis = _prior(episode, handle)
    log.info("grasp plan (dry run): grasp at %s m, pre-grasp joints %s rad, prior axis %s along %s",
             _vec(T_grasp[:3, 3]), _vec(q_pre), state.axis.joint_type.value, _vec(state.axis.direction))
    state.commanded.extend([kin.fk(q_pre), T_grasp])
    episode.view.grasp(episode.now(), T_grasp)
    state.estimates.append({"step": 0, "t": 0.0, "source": "plan (prior)", "axis": state.axis.to_dict(),
                            f"opened_{opening_unit(state.joint_type())}": 0.0, "vision": "dry run"})
    p = T_grasp[:3, 3]
    return StopReason.DRY_RUN, (f"planned: handle at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m, pre-grasp joints "
                                f"{np.round(q_pre, 3).tolist()}, {state.joint_type().value} prior axis; nothing moved")


def grasp(episode: Episode, handle: Handle) -> None:
    """Open the gripper, move to the pre-grasp configuration, approach straight and close on the handle."""
    clock = time.perf_counter()
    arm, kin, state = episode.arm, episode.kin, episode.state
    approach = episode.config.opening.approach_m
    T_grasp, opening, q_pre = _grasp_plan(episode, handle)
    log.info("grasp plan: grasp at %s m, approach %.3f m straight in, pre-grasp joints %s rad", _vec(T_grasp[:3, 3]),
             approach, _vec(q_pre))
    episode.view.grasp(episode.now(), T_grasp)
    arm.set_gripper(opening)
    move_to_joints(arm, q_pre, episode.joint_limits)
    _measure_torque_offset(episode)
    open_width = arm.state().gripper_width_m
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), approach, episode.line_limits(), episode.show_arm)
    _ease_off_press(episode)
    _close_and_check(episode, open_width, StopReason.GRASP_FAILED)
    state.open_width_m = open_width
    state.p_grasp = episode.tool()[:3, 3]
    state.timings["grasp_s"] += time.perf_counter() - clock


def probe_and_classify(episode: Episode, handle: Handle) -> None:
    """`--joint auto`: a short straight pull, then drawer or door from how the front turned and moved."""
    state, observer = episode.state, episode.observer
    probe = episode.config.opening.probe_pull_m
    _pull(episode, line_path(episode.tool(), handle.normal), probe, "probe pull")
    seen, first = observer.latest_view(), observer.first_look
    if seen is None:
        raise EpisodeStop(StopReason.TRACKING_LOST, "no frame was seen during the probe pull: check the camera")
    frame, mask = seen
    after = observer.points(frame, mask)
    turn = front_turn_deg(handle.normal, after, episode.tool()[:3, 3], first.body_box, viewpoint(frame))
    shift = front_shift_m(first.points, after, handle.center, handle.normal)
    state.joint = classify_joint(turn, shift, probe)
    observer.set_joint(state.joint)
    if state.joint is JointType.REVOLUTE:  # the straight probe slips on a door's arc: count the turn seen
        state.p_grasp, state.opened_before = episode.tool()[:3, 3], float(np.radians(turn))
    state.estimates.append({"step": 0, "t": episode.now(), "source": "probe pull", "axis": None,
                            "classified": state.joint.value, "front_turn_deg": turn, "front_shift_m": shift})
    step_log.info("probe pull: the front turned %.1f deg and moved %.3f m out: a %s (%s)", turn, shift,
                  "door" if state.joint is JointType.REVOLUTE else "drawer", state.joint.value)


def first_pull(episode: Episode, handle: Handle) -> None:
    """A first opening before any estimate: straight out along the front normal (drawer, and the paper's
    policy), or a small arc about the door's likely hinge (a front's edge: `_door_side_pull`); `first_pull_m` of the
    handle's travel, or less where the steps' goal (target plus overshoot) is nearer."""
    state, opening_cfg = episode.state, episode.config.opening
    revolute = state.joint is JointType.REVOLUTE
    if revolute:
        state.axis = _prior(episode, handle)
    left = episode.target() + OVERSHOOT[state.joint_type()] - state.opened_before  # m, or rad for a door
    length = min(opening_cfg.first_pull_m, left * (_door_radius(episode) if revolute else 1.0))
    if length <= 0.0:  # the probe pull already went past the goal
        return
    if revolute and not episode.policy.straight_door(state.joint):
        length -= _door_side_pull(episode, handle, length)
        if length > 0.0:
            _pull(episode, door_arc(episode.tool(), state.axis, handle.found), length / _door_radius(episode),
                  "first pull", episode.arc_limits())
    else:
        _drawer_pull(episode, handle.normal, length, "first pull")


def _moved_side(episode: Episode, handle: Handle, pulled_m: float) -> float:
    """`hinge_side` from the pixels on the object both in the first frame and in the latest (the camera stays put)."""
    seen, first = episode.observer.latest_view(), episode.observer.first_look
    if seen is None:
        return 0.0
    frame, mask = seen
    both = mask & first.mask & np.isfinite(frame.depth_m) & np.isfinite(first.frame.depth_m) & \
        (frame.depth_m > 0) & (first.frame.depth_m > 0)
    K = frame.intrinsics.K
    before = depth_to_points(first.frame.depth_m, K, both, first.frame.T_base_camera)
    after = depth_to_points(frame.depth_m, K, both, frame.T_base_camera)
    return hinge_side(before, after, handle, pulled_m)


def _door_radius(episode: Episode) -> float:
    """Metres of handle travel per radian about the current axis (at least MIN_DOOR_RADIUS_M)."""
    axis = episode.state.axis
    return max(float(np.linalg.norm(np.cross(axis.direction, episode.state.p_grasp - axis.origin))),
               MIN_DOOR_RADIUS_M)


def _door_side_pull(episode: Episode, handle: Handle, length: float) -> float:
    """When the front does not tell which edge the hinge is on (`hinge_side_sure`), a short straight pull
    (`probe_pull_m`, at most `length`) before any arc; the hinge is then the edge on the side where the front moved
    out the less (`hinge_side`; the far edge when that does not tell). Returns the handle's travel pulled (m)."""
    state, observer = episode.state, episode.observer
    first, pointed = observer.first_look, observer.pointed
    corners = None if pointed is None else pointed.front.corners
    if hinge_side_sure(handle, first.points, first.body_box, corners):
        return 0.0
    probe = min(episode.config.opening.probe_pull_m, length)
    _pull(episode, line_path(episode.tool(), handle.normal), probe, "first pull (straight: the hinge's side unsure)")
    side = _moved_side(episode, handle, probe)
    state.axis = _prior(episode, handle, side)
    seen_side = {1.0: "its right", -1.0: "its left"}.get(side, "neither side")
    step_log.info("first pull: the handle's place on its front left the hinge's side open; after %.3f m straight "
                  "the front moved out the less toward %s (as the camera sees it)", probe, seen_side)
    return probe


def estimate(episode: Episode, pull: np.ndarray) -> tuple[Axis, str]:
    """The axis to act on and where it came from; updates the opening. The open-loop policy estimates once,
    after the first pull, and keeps that axis. Before any usable estimate: the door's hinge prior, or a line
    along the front normal."""
    clock = time.perf_counter()
    state, vision = episode.state, episode.observer.latest_axis()
    if not episode.policy.re_estimates:
        chosen, source = (state.axis, "fixed") if state.estimated else _estimate_once(episode, pull)
        state.estimated = True
    else:
        joint = state.joint or (vision.joint_type if isinstance(vision, Axis) else None)
        trajectory = _grip_path_axis(np.array(state.measured), joint)
        strained = state.across_force_n >= episode.config.opening.force_cue_n
        result, source = choose_axis(vision, trajectory, state.joint, state.opened, episode.config.opening, strained)
        chosen = orient_axis(result, _measured_pull(episode, pull), state.p_grasp) \
            if isinstance(result, Axis) else None
        _follow_vision_alone(episode, vision, pull)
        # once a step about the hinge prior was blocked across its arc (`_may_go_on_blocked`), the grip's path mostly
        # followed the prior: while the pulls strain, the front's turn shows the hinge
        turned = _hinge_seen_turning(episode, pull) if strained and state.prior_blocks and not state.estimated \
            else None
        state.estimated |= chosen is not None and turned is None
        if turned is not None:
            chosen, source = turned, "front turn"
        elif chosen is None:
            chosen = state.axis if state.axis is not None else Axis(JointType.PRISMATIC, state.p_grasp, pull,
                                                                    confidence=0.0)
            source = f"prior ({source})"
    state.axis = chosen
    state.opened = state.opened_before + opening(chosen, state.p_grasp, episode.tool()[:3, 3])
    _read_drawer_lag(episode, chosen)
    _log_estimate(episode, chosen, source)
    state.timings["estimate_s"] += time.perf_counter() - clock
    return chosen, source


def _hinge_seen_turning(episode: Episode, pull: np.ndarray) -> Axis | None:
    """The door's hinge where the closed front meets the front as the camera sees it turned around the grip now
    (`hinge_from_turn`; the hinge prior gives the closed front's plane); None when the front turned too little to
    tell, or for a policy acting on vision alone."""
    state, observer = episode.state, episode.observer
    seen, first = observer.latest_view(), observer.first_look
    if seen is None or first is None or state.handle is None or state.axis is None \
            or state.axis.joint_type is not JointType.REVOLUTE or episode.config.opening.acting_fusion == "vision":
        return None
    frame, mask = seen
    grip = episode.tool()[:3, 3]
    normal = front_normal(observer.points(frame, mask), grip, first.body_box, viewpoint(frame))
    return hinge_from_turn(state.axis.origin, state.handle.center, grip, pull, normal, MIN_SEEN_TURN_DEG)


def _grip_path_axis(poses: np.ndarray, joint: JointType | None) -> AxisResult:
    """The axis fitted to the tool poses measured while pulling (NoAxis before any pull was measured: the first one
    ran out of reach). A parallel gripper's fingers let the handle turn in them, so its own turn is not the door's: a
    hinge is fitted to the grip point's path alone (the turn still helps tell a hinge from a slide)."""
    if len(poses) == 0:
        return NoAxis("no pull measured yet")
    turns = None if joint is JointType.REVOLUTE else Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    return fit_trajectory(poses[:, :3, 3], turns, joint)


def _follow_vision_alone(episode: Episode, vision: AxisResult, pull: np.ndarray) -> None:
    """Keep what the loop would act on with vision alone (fusion "vision"), to measure the other cues against."""
    state = episode.state
    alone, _ = choose_axis(vision, NoAxis("not used"), state.joint, state.opened,
                           episode.config.opening.model_copy(update={"fusion": "vision"}))
    if isinstance(alone, Axis):
        state.vision_axis = orient_axis(alone, _measured_pull(episode, pull), state.p_grasp)


def _estimate_once(episode: Episode, pull: np.ndarray) -> tuple[Axis, str]:
    """The open loop's one estimate: vision's axis of the expected joint type however confident, else the
    prior."""
    state, vision = episode.state, episode.observer.latest_axis()
    if isinstance(vision, Axis) and (state.joint is None or vision.joint_type is state.joint):
        return orient_axis(vision, _measured_pull(episode, pull), state.p_grasp), "vision (once)"
    prior = state.axis if state.axis is not None else Axis(JointType.PRISMATIC, state.p_grasp, pull, confidence=0.0)
    return prior, "prior (once)"


def step(episode: Episode, axis: Axis, source: str) -> None:
    """One axis-guided step, after checking the step count and the time left."""
    state, cfg = episode.state, episode.config.opening
    if state.steps >= cfg.max_steps:
        raise EpisodeStop(StopReason.MAX_STEPS, f"{cfg.max_steps} steps made, opened "
                          f"{_shown(episode, state.opened):.3f}")
    if episode.now() > cfg.timeout_s:
        raise EpisodeStop(StopReason.TIMEOUT, f"{cfg.timeout_s:.0f} s of arm time used, opened "
                          f"{_shown(episode, state.opened):.3f}")
    path, length, limits = _step_path(episode, axis)
    if axis.joint_type is JointType.PRISMATIC:
        _drawer_pull(episode, axis.direction, length, f"step {state.steps}: {source}", step=True)
        return
    try:
        _pull(episode, path, length, f"step {state.steps}: {source}", limits, step=True)
    except IKError as out_of_reach:
        if not _may_turn_back(episode, axis):
            raise
        regrasp_turned(episode, axis, out_of_reach)
    except EpisodeStop as stop:
        if stop.reason is not StopReason.BLOCKED or not _may_go_on_blocked(episode, axis):
            raise


def _may_go_on_blocked(episode: Episode, axis: Axis) -> bool:
    """Whether a door's step that ended blocked may go on: it followed the hinge prior (no estimate acted on yet),
    the door pressed across its arc (`force_cue_n` or more: it went its own way, the prior is off), the gripper
    still holds it, few such steps went on (MAX_PRIOR_BLOCKS) and the front turned enough to place the hinge
    (`_hinge_seen_turning`), which the next estimate then acts on."""
    state = episode.state
    if axis.joint_type is not JointType.REVOLUTE or state.estimated or state.prior_blocks >= MAX_PRIOR_BLOCKS \
            or state.across_force_n < episode.config.opening.force_cue_n or not episode.gripping() \
            or state.handle is None or _hinge_seen_turning(episode, state.handle.normal) is None:
        return False
    state.prior_blocks += 1
    step_log.info("step %d blocked %.0f N across its arc about the hinge prior: the front turned otherwise, going on "
                  "about the hinge its turn shows", state.steps - 1, state.across_force_n)
    return True


def _may_turn_back(episode: Episode, axis: Axis) -> bool:
    """Whether a door's arc that ran out of reach may go on from a grasp with the hand turned back: the arc turns
    the tool with the door, the gripper still holds the handle and few such re-grasps were made."""
    state = episode.state
    return (axis.joint_type is JointType.REVOLUTE and not episode.policy.straight_door(axis.joint_type)
            and state.handle is not None and _turns_with_door(episode.tool(), axis, state.handle.found)
            and episode.gripping() and state.turned_regrasps < MAX_TURNED_REGRASPS)


def _drawer_pull(episode: Episode, direction: np.ndarray, length: float, label: str, step: bool = False) -> None:
    """A straight pull along `direction` (a drawer's axis, or the front normal before any); when it runs out of the
    arm's reach with the gripper holding the handle, the arm takes the handle again from a configuration that carries
    the rest of the pull (`reseat`)."""
    try:
        _pull(episode, line_path(episode.tool(), direction), length, label, episode.line_limits(), step)
    except IKError as out_of_reach:
        state = episode.state
        if state.joint_type() is not JointType.PRISMATIC or not episode.gripping() or state.reseats >= MAX_RESEATS:
            raise
        reseat(episode, direction, out_of_reach)


def reseat(episode: Episode, direction: np.ndarray, out_of_reach: IKError) -> None:
    """The drawer's pull along `direction` ran out of the arm's reach (`out_of_reach`, a joint at its limit or a
    singularity): count the travel so far, open, back off along the approach, move to the pre-grasp joints that carry
    the rest of the pull from the same grasp (`pregrasp_configuration`), come back and close; later travel counts
    from the new grip. EpisodeStop("ik infeasible") when no configuration carries the rest."""
    arm, kin, state = episode.arm, episode.kin, episode.state
    T_hold = episode.tool()
    state.opened = state.opened_before + max(0.0, float((T_hold[:3, 3] - state.p_grasp) @ direction))
    rest = max(episode.target() + OVERSHOOT[JointType.PRISMATIC] - state.opened, GOAL_TOLERANCE[JointType.PRISMATIC])
    try:
        q = pregrasp_configuration(kin, arm.state().q, T_hold, _line_pulls(T_hold, direction, rest), RETREAT_M)
    except IKError:
        reach = float(np.linalg.norm(T_hold[:2, 3]))
        raise EpisodeStop(StopReason.IK_INFEASIBLE, f"{out_of_reach}; at {state.opened:.3f} m the drawer's handle is "
                          f"{reach:.2f} m from the arm's base axis and no arm configuration carries the rest of the "
                          "pull from there: stand the robot farther from the cabinet or ask for a shorter opening"
                          ) from out_of_reach
    step_log.info("the pull is out of reach at %.3f m (%s): taking the handle again from another arm configuration",
                  state.opened, out_of_reach)
    arm.set_gripper(state.open_width_m)
    episode.wait(CLOSE_TIME_S)
    follow_cartesian_path(arm, kin, line_path(T_hold, -T_hold[:3, 2]), RETREAT_M, episode.line_limits(),
                          episode.show_arm)
    move_to_joints(arm, q, episode.joint_limits, episode.show_arm)
    episode.wait(SETTLE_S)
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), RETREAT_M, episode.line_limits(), episode.show_arm)
    _close_and_check(episode, state.open_width_m, StopReason.GRASP_LOST, "re-grasp after the pull ran out of reach "
                     "failed: ")
    state.reseats += 1
    state.opened_before, state.p_grasp = state.opened, episode.tool()[:3, 3]


def regrasp_turned(episode: Episode, axis: Axis, out_of_reach: IKError) -> None:
    """The door's arc runs out of the arm's reach (`out_of_reach`) with the hand turned with the door: swing the hand
    back toward the robot about the vertical line through the handle's grip centre (`_turned_grasp`) and count the
    opening from the new grip. A door that stays where it is left is let go for the swing (the handle stays between
    the open fingers) and held again after it; a self-closing one (`_closing_push`) stays held, the handle turning
    between the fingers (`_swing_held`). EpisodeStop("ik infeasible") when no such swing keeps clear of the scene
    and the door and carries the rest of the arc, or when a self-closing door's handle does not turn in the
    fingers."""
    arm, state = episode.arm, episode.state
    plan = _turned_grasp(episode, axis)
    if plan is None:
        raise EpisodeStop(StopReason.IK_INFEASIBLE, f"{out_of_reach}; at {_shown(episode, state.opened):.0f} deg "
                          "the door's handle cannot be held again with the hand turned back toward the robot either "
                          "(no such grasp keeps clear of the scene and the door and carries the rest of the arc): "
                          "stand the robot nearer the door's hinge side or ask for a smaller opening")
    swing, yaw = plan
    push = _closing_push(episode, axis)
    if push is not None and push[0] > SELF_CLOSING_N:
        step_log.info("the arc is out of reach at %.1f deg (%s): the door pushes the handle toward closed with "
                      "%.1f N (friction %.1f N), so the hand stays closed on it and turns back %.0f deg about it",
                      _shown(episode, state.opened), out_of_reach, *push, np.degrees(yaw))
        _swing_held(episode, swing, yaw, push[0])
    else:
        step_log.info("the arc is out of reach at %.1f deg (%s): holding the handle again with the hand turned back "
                      "%.0f deg", _shown(episode, state.opened), out_of_reach, np.degrees(yaw))
        arm.set_gripper(state.open_width_m)
        episode.wait(CLOSE_TIME_S)
        open_width = arm.state().gripper_width_m
        T = episode.tool()
        episode.view.grasp(episode.now(), swing(T)(yaw))
        follow_cartesian_path(arm, episode.kin, swing(T), yaw, episode.arc_limits(), episode.show_arm)
        _close_and_check(episode, open_width, StopReason.GRASP_LOST, "re-grasp with the hand turned back failed: ")
    state.turned_regrasps += 1
    state.opened_before, state.p_grasp = state.opened, episode.tool()[:3, 3]


def _closing_push(episode: Episode, axis: Axis) -> tuple[float, float] | None:
    """(push, friction), N: how hard the held door pushes its handle toward closed by itself and the friction it
    moves against (`closing_push_n`), from the force the hand applies along the door's opening direction while it
    eases the door SELF_CLOSING_PROBE_RAD back toward closed and then carries it open again. None when the arm
    measures no joint torques."""
    closing = _force_along_arc(episode, axis, -1.0)
    opening_n = None if closing is None else _force_along_arc(episode, axis, 1.0)
    if closing is None or opening_n is None:
        return None
    return closing_push_n(opening_n, closing), (opening_n - closing) / 2.0


def _force_along_arc(episode: Episode, axis: Axis, sign: float) -> float | None:
    """The mean force (N) the hand applies along the door's opening direction while it carries the door
    SELF_CLOSING_PROBE_RAD along its arc (`sign` 1: open, -1: toward closed), slowly (`_slow_arc`) and compliant as
    a pull is, over the whole motion (the arm's inertia speeding up and slowing down cancels). None without measured
    torques."""
    arm, kin, handle = episode.arm, episode.kin, episode.state.handle
    compliance = episode.compliance.with_force_limit(episode.config.opening.pull_force_limit_n)
    wrench = WrenchEstimator(kin, compliance.filter_time_constant_s, compliance.torque_offset)
    along: list[float] = []

    def on_tick(state: ArmState, _t: float) -> bool:
        w = wrench.update(state)
        if w is not None:
            along.append(float(w[:3] @ opening_direction(axis, held_centre(kin.fk(state.q), handle))))
        episode.show_arm(state)
        return True

    path = door_arc(episode.tool(), replace(axis, direction=sign * np.asarray(axis.direction)), handle.found)
    arm.set_compliance(True)
    try:
        follow_cartesian_path(arm, kin, path, SELF_CLOSING_PROBE_RAD, _slow_arc(episode), on_tick,
                              compliance=compliance)
    finally:
        arm.set_compliance(False)
    return float(np.mean(along)) if along else None


def _held_swing_limit(episode: Episode) -> float | None:
    """The force bound of a swing about a held handle: a pull's, plus the grip's squeeze, which moves onto one finger
    as the pads turn about the handle (the arm then feels it across the fingers, as in `_centre_on_handle`)."""
    limit = episode.config.opening.pull_force_limit_n
    return None if limit is None else limit + episode.grip_force_n


def _slow_arc(episode: Episode) -> MotionLimits:
    """The arc's limits at HELD_SWING_SPEED_SHARE of its speed (and of its acceleration and jerk)."""
    limits = episode.arc_limits()
    return MotionLimits(*(HELD_SWING_SPEED_SHARE * np.asarray(x) for x in (limits.v_max, limits.a_max, limits.j_max)))


def _swing_held(episode: Episode, swing: Callable[[np.ndarray], PathFn], yaw: float, push_n: float) -> None:
    """Swing the hand back by `yaw` about the handle's vertical line still closed on it, slowly, compliant and
    force-bounded (`_held_swing_limit`): a round bar turns between the pads. EpisodeStop("ik infeasible") when the
    swing stops short (the handle does not turn in the fingers) or the grip slips: the door stays held where it
    stands."""
    arm, kin, state = episode.arm, episode.kin, episode.state
    T = episode.tool()
    episode.view.grasp(episode.now(), swing(T)(yaw))
    arm.set_compliance(True)
    try:
        result = follow_cartesian_path(arm, kin, swing(T), yaw, _slow_arc(episode), episode.show_arm,
                                       compliance=episode.compliance.with_force_limit(_held_swing_limit(episode)))
    finally:
        arm.set_compliance(False)
    if result.outcome is not Outcome.COMPLETED or not episode.gripping():
        raise EpisodeStop(StopReason.IK_INFEASIBLE, f"the door's arc is out of the arm's reach at "
                          f"{_shown(episode, state.opened):.0f} deg, and the door closes by itself (it pushes the "
                          f"handle toward closed with {push_n:.1f} N) so it cannot be let go to hold it again, and its "
                          f"handle did not turn in the fingers ({result.reason}): stand the robot nearer the door's "
                          "hinge side or ask for a smaller opening")


def _turned_grasp(episode: Episode, axis: Axis) -> tuple[Callable[[np.ndarray], PathFn], float] | None:
    """How to swing the hand back toward the robot (a pose -> its swing about the vertical line through the handle's
    grip centre, where the arm holds it now) and how far (rad): the first of DOOR_REGRASP_YAWS_DEG (at most the opening
    so far) whose grasp keeps clear of the first frame's scene and of the door where it now stands (`clear_grasps` on
    the handle as that grasp holds it, `held_as`) and from which the arm follows, without changing branch, the swing
    and the rest of the arc, or half of it; None when none does, or without a pointed part (no scene to
    check)."""
    state, pointed, kin = episode.state, episode.observer.pointed, episode.kin
    if pointed is None:
        return None
    handle, T, q = state.handle, episode.tool(), episode.arm.state().q
    centre = held_centre(T, handle)
    remaining = _goal(episode, axis) - state.opened
    origin, normal = door_plane(handle, centre, axis, state.opened, pointed.handle.relief_m)
    door = replace(scene_tree(episode.observer.first_look.frame, pointed), origin=origin, normal=normal)

    def swing(T_from: np.ndarray) -> PathFn:
        return arc_path(T_from, centre, -axis.direction)

    def pulls(T_grasp: np.ndarray) -> list[list[np.ndarray]]:
        path = door_arc(T_grasp, axis, handle.found)
        return [pull_poses(path, arc, PLANNED_ARC_STEP_RAD) for arc in (remaining, remaining / 2)]

    for yaw in np.radians(DOOR_REGRASP_YAWS_DEG):
        T_grasp = swing(T)(yaw)
        if yaw > state.opened or not _clears(held_as(T_grasp, handle), door, T_grasp, pulls,
                                             episode.gripper.max_opening_m):
            continue
        for pull in pulls(T_grasp):
            try:
                kin.solve_path([T, *pull_poses(swing(T), yaw, PLANNED_ARC_STEP_RAD), *pull], q)
            except IKError:
                continue
            return swing, float(yaw)
    return None


def _clears(handle: Handle, door: Scene, T_grasp: np.ndarray, pulls: Callable, max_opening_m: float) -> bool:
    """Whether the scene clearance lets the gripper hold `handle` near `T_grasp`: one of its clear grasps lies within
    SAME_GRASP_M and SAME_GRASP_RAD of it (the arm's grasp follows the door's estimated turns, the handle the
    estimated opening)."""
    try:
        grips = clear_grasps(handle, door, pulls, RETREAT_M, max_opening_m)
    except EpisodeStop:
        return False
    return any(np.linalg.norm(T[:3, 3] - T_grasp[:3, 3]) < SAME_GRASP_M
               and Rotation.from_matrix(T[:3, :3].T @ T_grasp[:3, :3]).magnitude() < SAME_GRASP_RAD
               for T, _ in grips)


def regrasp(episode: Episode) -> None:
    """Open, back off along the approach, find the handle again in a fresh frame near where it was held or,
    released, gone back along the estimated path (a door swinging shut), approach it and close. The opening is
    the one measured before the slipping pull (its share is not counted: the arm errs toward opening further),
    or less where the handle is found gone back; later travel counts from the new grip."""
    arm, kin, state = episode.arm, episode.kin, episode.state
    held = episode.tool()[:3, 3]
    arm.set_gripper(state.open_width_m)
    episode.wait(CLOSE_TIME_S)
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, -T[:3, 2]), RETREAT_M, episode.line_limits(), episode.show_arm)
    frame, points, robot = episode.observer.look(arm.state())
    handle = _slipped_handle(episode, frame, points, robot, held)
    if handle is None:
        raise EpisodeStop(StopReason.GRASP_LOST, f"the handle slipped out of the gripper and was not found again "
                          f"within {REGRASP_RADIUS_M * 100:.0f} cm of where it was held or of the estimated path "
                          "back to the start: check the view of the handle")
    T_grasp = grasp_pose(handle)
    episode.view.grasp(episode.now(), T_grasp)
    move_to_pose(arm, kin, pregrasp_pose(T_grasp, RETREAT_M), episode.joint_limits)
    episode.wait(SETTLE_S)
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), RETREAT_M, episode.line_limits(), episode.show_arm)
    _close_and_check(episode, state.open_width_m, StopReason.GRASP_LOST, "re-grasp after a slip failed: ")
    p_new = episode.tool()[:3, 3]
    if state.axis is not None:
        state.opened = min(state.opened, state.opened_before + opening(state.axis, state.p_grasp, p_new))
    state.opened_before, state.p_grasp = state.opened, p_new


def _slipped_handle(episode: Episode, frame: Frame, points: np.ndarray, robot: np.ndarray, held: np.ndarray
                    ) -> Handle | None:
    """The handle found near where it was `held`, else near where the part would be gone back by some of its
    opening along the estimated axis (every REGRASP_RADIUS_M of the path, nearest first): on the pointed front
    seen there when the user pointed, else the points protruding from the front there."""
    state, eye = episode.state, viewpoint(frame)
    travel = 0.0 if state.axis is None else \
        max(state.opened, state.opened_before + opening(state.axis, state.p_grasp, held))
    for near in back_along_path(state.axis, held, travel, REGRASP_RADIUS_M):
        handle = _pointed_near(episode, frame, robot, near) if episode.observer.pointed is not None else None
        if handle is None:
            handle = find_handle(protruding_points(points, near, eye), points, episode.observer.first_look.body_box,
                                 eye, state.joint_type() is JointType.REVOLUTE)
        if handle is not None:
            return handle
    return None


def _pointed_near(episode: Episode, frame: Frame, robot: np.ndarray, near: np.ndarray) -> Handle | None:
    """The handle of the front seen at `near` (base frame) in `frame`, pointed at as the user did on the first
    frame, when it lies within REGRASP_RADIUS_M of `near`: the same front, moved; None otherwise."""
    u, v = points_to_pixels(near, frame.intrinsics.K, frame.T_base_camera)[0]
    if not Pointer(u, v).inside(*frame.depth_m.shape[::-1]):  # behind the camera (NaN) or off the image
        return None
    try:
        found = point_at(frame, robot, Pointer(u, v), gripper=episode.gripper)
    except PointerError:
        return None
    handle = pointed_handle(found.handle, episode.state.joint_type() is JointType.REVOLUTE)
    close = np.linalg.norm(handle.center - near) < REGRASP_RADIUS_M and found.handle.graspability > 0.0
    return handle if close else None


# --- helpers ---------------------------------------------------------------------------------------------


def _pull(episode: Episode, path: PathFn, length: float, label: str, limits: MotionLimits | None = None,
          step: bool = False) -> None:
    """A pull, then its checks: a slip re-grasps once (a second one is "grasp lost"); a blocked motion stops."""
    result = episode.pull(path, length, label, limits, step)
    if not episode.gripping():
        if episode.state.regrasped:
            raise EpisodeStop(StopReason.GRASP_LOST, f"the handle slipped out of the gripper again during "
                              f"{label}, after one re-grasp: the pull needs more force than the grasp holds")
        episode.state.regrasped = True
        regrasp(episode)
    elif result.outcome is Outcome.BLOCKED:
        raise EpisodeStop(StopReason.BLOCKED, f"no more motion during {label} ({result.reason}): the joint is at "
                          "its limit or locked, or the object presses on the arm itself (a door's sweep): check "
                          "the arm's clearance")


def _measure_torque_offset(episode: Episode) -> None:
    """At the pre-grasp pose, touching nothing: the joint torques' own offset (motor-current torque sensing reads
    a few percent of each motor's peak torque there), the mean over SETTLE_S once the arm has settled, which every
    later force reading of the episode subtracts (`Compliance.torque_offset`)."""
    episode.wait(SETTLE_S)
    states = []
    for _ in range(round(SETTLE_S / episode.arm.control_period_s)):
        episode.arm.sync()
        states.append(episode.arm.state())
    episode.compliance = episode.compliance.with_torque_offset(torque_offset(episode.kin, states))


def _ease_off_press(episode: Episode) -> None:
    """A handle nearer than seen (a short knob, the calibration's error) leaves the palm pushing on it at the
    approach's end. The first pull would start by releasing that push, which its force bound reads as resistance
    (a pull held still at 0 deg): back off along the approach, before closing, until the tool no longer pushes.
    Arms that measure no joint torques skip this."""
    arm, kin = episode.arm, episode.kin
    wrench = WrenchEstimator(kin, 0.0, episode.compliance.torque_offset)
    for _ in range(round(MAX_EASE_M / EASE_STEP_M)):
        state = arm.state()
        w = wrench.update(state)
        T = kin.fk(state.q)
        if w is None or w[:3] @ T[:3, 2] < PRESS_N:
            return
        follow_cartesian_path(arm, kin, line_path(T, -T[:3, 2]), EASE_STEP_M, episode.line_limits(),
                              episode.show_arm)
        episode.wait(SETTLE_S)


def _close_and_check(episode: Episode, open_width: float, failure: StopReason, context: str = "") -> None:
    """Close on the handle; when one finger alone pressed it, centre it (`_centre_on_handle`), open and close again
    so that both fingers squeeze it. EpisodeStop(`failure`) when the gripper closed on nothing."""
    width = _close(episode, open_width, failure, context)
    moved = _centre_on_handle(episode, width)
    if moved:
        log.info("one finger alone pressed the handle (closed to %.1f mm): the tool moved %.1f mm toward it and "
                 "closed again", width * 1e3, moved * 1e3)
        episode.arm.set_gripper(open_width)
        episode.wait(CLOSE_TIME_S)
        _close(episode, open_width, failure, context)


def _close(episode: Episode, open_width: float, failure: StopReason, context: str) -> float:
    """Close the gripper; the width it stopped at. EpisodeStop(`failure`) when it closed on nothing."""
    episode.arm.set_gripper(0.0, episode.grip_force_n)
    episode.wait(CLOSE_TIME_S)
    width = episode.arm.state().gripper_width_m
    if not MIN_GRASP_WIDTH_M < width < open_width - OPEN_MARGIN_M:
        raise EpisodeStop(failure, f"{context}gripper closed to {width * 1e3:.1f} mm (open {open_width * 1e3:.1f} "
                          "mm): it missed the handle; check the handle detection and the camera calibration")
    return width


def _centre_on_handle(episode: Episode, width: float) -> float:
    """How far (m) the tool moved to centre the handle between the closed fingers. Each finger closes to the
    gripper's middle: a handle lying off it by more than half its thickness stops one finger while the other closes
    short of it, and the arm then feels that finger's squeeze across the fingers (the tool pushes the handle toward
    the middle). Still squeezing, the tool moves toward the touching finger in CENTRING_STEP_M steps until the other
    finger presses too (the force across them drops), at most the closed `width` (the touching finger is no farther
    from the middle). Arms that measure no joint torques do not move."""
    arm, kin = episode.arm, episode.kin
    moved = 0.0
    while moved < width:
        wrench = WrenchEstimator(kin, 0.0, episode.compliance.torque_offset)
        states = []
        for _ in range(round(REST_READING_S / arm.control_period_s)):
            arm.sync()
            states.append(arm.state())
        w = wrench.start(states)
        T = kin.fk(states[-1].q)
        across = 0.0 if w is None else float(w[:3] @ T[:3, 1])
        if abs(across) < ONE_FINGER_SHARE * episode.grip_force_n:
            break
        follow_cartesian_path(arm, kin, line_path(T, -np.sign(across) * T[:3, 1]), CENTRING_STEP_M,
                              episode.line_limits(), episode.show_arm)
        moved += CENTRING_STEP_M
    return moved


def _grasp_plan(episode: Episode, handle: Handle) -> tuple[np.ndarray, float, np.ndarray]:
    """The grasp pose, how wide the fingers open for it and the pre-grasp joints: with a pointed part, the first
    grasp whose approach and first pull keep clear of the scene the first frame showed and that the arm carries
    (EpisodeStop when none keeps clear, IKError when the arm carries none); else the usual one, fully open."""
    pointed, widest, kin = episode.observer.pointed, episode.gripper.max_opening_m, episode.kin
    approach, q = episode.config.opening.approach_m, episode.arm.state().q
    if pointed is None:
        T = grasp_pose(handle)
        opening = widest if handle.open_m is None else handle.open_m
        return T, opening, pregrasp_configuration(kin, q, T, _planned_pulls(episode, handle, T), approach)
    scene = scene_tree(episode.observer.first_look.frame, pointed)
    refused = None
    for T, opening in clear_grasps(handle, scene, lambda T: _planned_pulls(episode, handle, T), approach, widest):
        try:
            return T, opening, pregrasp_configuration(kin, q, T, _planned_pulls(episode, handle, T), approach)
        except IKError as e:
            refused = refused or e
    raise refused


def _planned_pulls(episode: Episode, handle: Handle, T_grasp: np.ndarray) -> list[list[np.ndarray]]:
    """The pulls the pre-grasp configuration is planned for, most wanted first: a door's arc about its likely
    hinge (PLANNED_DOOR_ARCS_DEG; the wrist turns with the door from the start), then straight out along the front
    normal, the drawer's whole pull (or PLANNED_DOOR_REACH_M for a door) and halves of it down to
    MIN_PLANNED_PULL_M."""
    pulls = []
    revolute = episode.state.joint is JointType.REVOLUTE
    if revolute and not episode.policy.straight_door(episode.state.joint):
        prior = _prior(episode, handle)
        pulls += [pull_poses(door_arc(T_grasp, prior, handle.found), np.radians(arc), PLANNED_ARC_STEP_RAD)
                  for arc in PLANNED_DOOR_ARCS_DEG]
    length = PLANNED_DOOR_REACH_M if revolute else \
        episode.config.opening.target_distance_m + OVERSHOOT[JointType.PRISMATIC]
    return pulls + _line_pulls(T_grasp, handle.normal, length)


def _line_pulls(T_grasp: np.ndarray, direction: np.ndarray, length: float) -> list[list[np.ndarray]]:
    """Straight pulls from the grasp pose along `direction`, `length` and halves of it down to MIN_PLANNED_PULL_M (or
    `length` alone when shorter), each as tool poses every PLANNED_LINE_STEP_M."""
    pulls = []
    while True:
        pulls.append(pull_poses(line_path(T_grasp, direction), length, PLANNED_LINE_STEP_M))
        if length <= MIN_PLANNED_PULL_M:
            return pulls
        length /= 2


def _prior(episode: Episode, handle: Handle, side: float = 0.0) -> Axis:
    """The axis before any motion: a door's likely hinge (on `side` of the handle when given: `hinge_prior`), or a
    line along the front normal."""
    if episode.state.joint is JointType.REVOLUTE:
        first, pointed = episode.observer.first_look, episode.observer.pointed
        return hinge_prior(handle, first.points, first.body_box, None if pointed is None else pointed.front.corners,
                           side)
    return Axis(JointType.PRISMATIC, handle.center, handle.normal, confidence=0.0)


def _measured_pull(episode: Episode, pull: np.ndarray) -> np.ndarray:
    """The direction the grip point actually moved since the grasp, or the front normal before that."""
    moved = episode.tool()[:3, 3] - episode.state.p_grasp
    return moved if np.linalg.norm(moved) > 0.01 else pull


def _read_drawer_lag(episode: Episode, axis: Axis) -> None:
    """A drawer lags a stretched grasp: trust the camera's reading of the opening when it is a little short of
    the gripper's (more than MAX_DRAWER_LAG_M short is a misreading, not a lag)."""
    window = episode.observer.window()
    if axis.joint_type is not JointType.PRISMATIC or not window:
        return
    state = episode.state
    seen = seen_opening(window[-1].moving, episode.observer.first_look.points, axis.direction)
    if seen is not None and state.opened - MAX_DRAWER_LAG_M <= seen < state.opened:
        state.opened = seen


def _check_followed(episode: Episode, axis: Axis) -> None:
    """EpisodeStop(NOT_FOLLOWED) when the gripper carried a drawer FOLLOW_CHECK_M or more and the camera still sees
    the front where the user pointed, in its place: the arm moved something else (a neighbour's handle), or its
    grip slid along or off the handle. The first frame that shows the front gone settles it: a drawer carried
    farther shows its inside where its front stood, which may read the front's old depth again."""
    state = episode.state
    if axis.joint_type is not JointType.PRISMATIC or state.opened < FOLLOW_CHECK_M or state.followed:
        return
    still = episode.observer.pointed_still()
    state.followed = still is False
    if still:
        pointer = Pointer.of(episode.config.perception.point, episode.config.perception.box)
        raise EpisodeStop(StopReason.NOT_FOLLOWED, f"the gripper travelled {state.opened:.3f} m but the drawer "
                          f"pointed at ({pointer}) did not follow: it still stands where it was; the gripper holds "
                          "another part's handle or slid along its own; check which handle it grasped")


def _log_estimate(episode: Episode, axis: Axis, source: str) -> None:
    state, vision = episode.state, episode.observer.latest_axis()
    shown = _shown(episode, state.opened)
    state.opening_curve.append((episode.now(), state.opened))
    episode.view.axis(episode.now(), axis, shown, source)
    _show_step(episode)
    state.estimates.append({
        "step": state.steps, "t": episode.now(), "source": source, "axis": axis.to_dict(),
        f"opened_{opening_unit(state.joint_type())}": shown,
        "across_force_n": state.across_force_n,
        "vision": vision.reason if isinstance(vision, NoAxis)
        else f"{vision.joint_type.value}, confidence {vision.confidence:.3f}"})


def _show_step(episode: Episode) -> None:
    """The step's clouds in the viewer, when one shows the episode: the latest frame's object cloud, its moving
    part and the handle (the points protruding from the front near the gripper)."""
    seen = episode.observer.latest_view() if episode.view.showing else None
    if seen is None:
        return
    frame, mask = seen
    cloud = episode.observer.points(frame, mask)
    window = episode.observer.window()
    handle = protruding_points(cloud, episode.tool()[:3, 3], viewpoint(frame))
    episode.view.step_clouds(episode.now(), cloud, window[-1].moving if window else None, handle)


def _step_path(episode: Episode, axis: Axis) -> tuple[PathFn, float, MotionLimits]:
    """The next step: a line along a drawer, an arc about a door's axis, or for a policy that pulls doors
    straight a line along the arc's tangent (its steps in metres)."""
    state = episode.state
    remaining = _goal(episode, axis) - state.opened
    size = episode.policy.step_size(axis.joint_type, state.steps, episode.config.opening)
    T = episode.tool()
    if axis.joint_type is JointType.PRISMATIC:
        return line_path(T, axis.direction), min(size, remaining), episode.line_limits()
    if episode.policy.straight_door(axis.joint_type):
        tangent = np.cross(axis.direction, T[:3, 3] - axis.origin)
        radius = max(float(np.linalg.norm(tangent)), 0.05)
        return line_path(T, tangent), min(size, remaining * radius), episode.line_limits()
    kind = "" if state.handle is None else state.handle.found
    return door_arc(T, axis, kind), min(size, remaining), episode.arc_limits()


def door_arc(T: np.ndarray, axis: Axis, kind: str) -> PathFn:
    """The tool's arc about a door's axis from pose T, holding a handle of `kind` (`Handle.found`). Fingers closing
    along the hinge across a horizontal handle that lies along their pads (TURNING_HANDLES: a tab, a cup, a bar) let
    it turn between the pads as the door swings: the tool keeps its orientation, sparing the wrist the door's turn.
    Otherwise the tool turns with the door: a vertical bar (the hand's width lies in the swing), a knob (its stem
    would swing into the fingers), a pocket (its walls would)."""
    return arc_path(T, axis.origin, axis.direction, turn=_turns_with_door(T, axis, kind))


def _turns_with_door(T: np.ndarray, axis: Axis, kind: str) -> bool:
    """Whether the tool at pose T holding a handle of `kind` turns with the door (`door_arc`)."""
    along_hinge = abs(float(T[:3, 1] @ axis.direction)) >= HINGE_ALIGNED_COS
    return not (along_hinge and kind in TURNING_HANDLES)


def _goal(episode: Episode, axis: Axis) -> float:
    """Where the steps aim: the target plus the overshoot (m or rad)."""
    return episode.target() + OVERSHOOT[axis.joint_type]


def _shown(episode: Episode, value: float) -> float:
    """An opening in the units users read: m for a drawer, deg for a door."""
    return value * display_scale(episode.state.joint_type())
