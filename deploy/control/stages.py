"""The stages of an opening episode, in order; each reads and updates `episode.state` (SI units) and ends the
episode by raising `EpisodeStop` with a `StopReason`."""

from __future__ import annotations

import logging
import time

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.axis_pipeline import viewpoint
from deploy.control.classify import classify_joint, front_shift_m, front_turn_deg
from deploy.control.context import GOAL_TOLERANCE, OVERSHOOT, SETTLE_S, Episode
from deploy.control.door_regrasp import door_meets_hand
from deploy.control.grasp import (
    Handle,
    find_handle,
    front_normal,
    grasp_pose,
    hinge_prior,
    hinge_side,
    hinge_side_sure,
    pointed_handle,
    pregrasp_either_way,
    protruding_points,
    pull_poses,
)
from deploy.control.hand import (
    checked_pull,
    close_and_check,
    close_or_reach,
    door_arc,
    ease_off_press,
    measure_torque_offset,
    seat_in_pocket,
    turns_with_door,
)
from deploy.control.out_of_reach import PLANNED_ARC_STEP_RAD, line_pulls, regrasp_turned, reseat
from deploy.control.policy import (
    choose_axis,
    hinge_from_turn,
    holds_path,
    opening,
    orient_axis,
    seen_opening,
)
from deploy.control.scene_clearance import ranked_grasps, scene_tree
from deploy.control.state import EpisodeStop, StopReason, opening_unit
from deploy.control.view import step_log
from deploy.errors import PartHiddenError, PointerError
from deploy.geometry.clearance import parallel_gripper
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.estimators.trajectory import fit_trajectory
from deploy.geometry.types import Axis, AxisResult, JointType, NoAxis
from deploy.perception.base import Pointer
from drivers.arm.motion import (
    PathFn,
    arc_path,
    follow_cartesian_path,
    line_path,
    move_to_joints,
)
from drivers.arm.trajectory import MotionLimits
from drivers.errors import IKError

log = logging.getLogger(__name__)

MAX_DRAWER_LAG_M = 0.03  # how far a drawer may lag the gripper's travel (a stretched grasp)
ARM_TOUCH_PX = 100  # the arm's pixels touching the object's on the first frame: it may hide the handle
CLEAR_VIEW_TURNS_RAD = (0.7, -0.7, 1.2, -1.2)  # first-joint swings tried to take the arm out of the view
MIN_DOOR_RADIUS_M = 0.1  # the first arc's radius is taken as at least this
MIN_SEEN_TURN_DEG = 5.0  # a door's front seen turned less than this does not place its hinge (`hinge_from_turn`)
PLANNED_DOOR_ARCS_DEG = (45.0, 30.0, 15.0)  # a door's pre-grasp is planned for the longest of these arcs it carries
PLANNED_DOOR_REACH_M = 0.1  # ... or else for this much straight pull
MAX_TURNED_REGRASPS = 2
MAX_PRIOR_BLOCKS = 1  # a door's step blocked across its arc about the hinge prior goes on this often
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
        if episode.state.opened >= episode.goal(axis.joint_type) - GOAL_TOLERANCE[axis.joint_type]:
            return StopReason.TARGET_REACHED, f"opened {episode.shown(episode.state.opened):.3f} of " \
                                              f"{episode.shown(episode.target()):.3f}"
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
    measure_torque_offset(episode)
    open_width = arm.state().gripper_width_m
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), approach, episode.line_limits(), episode.show_arm)
    # into a drawer's pocket only: a door's turn would swing the pocket's walls into fingers set deeper in it
    pocket = handle.found == "recessed pull" and state.joint is JointType.PRISMATIC
    if pocket and seat_in_pocket(episode):  # the press left is eased holding the bar
        close_and_check(episode, open_width, StopReason.GRASP_FAILED)
        ease_off_press(episode)
    else:
        ease_off_press(episode)
        close_or_reach(episode, open_width)
    state.open_width_m = open_width
    state.p_grasp = episode.tool()[:3, 3]
    state.timings["grasp_s"] += time.perf_counter() - clock


def probe_and_classify(episode: Episode, handle: Handle) -> None:
    """`--joint auto`: a short straight pull, then drawer or door from how the front turned and moved."""
    state, observer = episode.state, episode.observer
    probe = episode.config.opening.probe_pull_m
    checked_pull(episode, line_path(episode.tool(), handle.normal), probe, "probe pull")
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
            checked_pull(episode, door_arc(episode.tool(), state.axis, handle.found), length / _door_radius(episode),
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
    checked_pull(episode, line_path(episode.tool(), handle.normal), probe,
                 "first pull (straight: the hinge's side unsure)")
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
        trajectory = _grip_path_axis(np.array(state.measured[state.grip_start:]), joint)
        strained = state.across_force_n >= episode.config.opening.force_cue_n
        result, source = choose_axis(vision, trajectory, state.joint, state.opened, episode.config.opening, strained)
        chosen = orient_axis(result, _measured_pull(episode, pull), state.p_grasp) \
            if isinstance(result, Axis) else None
        _follow_vision_alone(episode, vision, pull)
        # once a step about the hinge prior was blocked across its arc (`_may_go_on_blocked`), the grip's path mostly
        # followed the prior: while the pulls strain, the front's turn shows the hinge
        turned = _hinge_seen_turning(episode) if strained and state.prior_blocks and not state.estimated \
            else None
        state.estimated |= chosen is not None and turned is None
        if turned is not None:
            chosen, source, state.turn_hinge = turned, "front turn", turned
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


def _hinge_seen_turning(episode: Episode) -> Axis | None:
    """The door's hinge where the closed front meets the front as the camera sees it turned around the grip now
    (`hinge_from_turn`; the hinge prior gives the closed front's plane), or the one an earlier view placed when this
    one sees the front turned the other way round; None when the front turned too little to tell, or for a policy
    acting on vision alone."""
    state, observer = episode.state, episode.observer
    seen, first = observer.latest_view(), observer.first_look
    if seen is None or first is None or state.handle is None or state.axis is None \
            or state.axis.joint_type is not JointType.REVOLUTE or episode.config.opening.acting_fusion == "vision":
        return None
    frame, mask = seen
    grip = episode.tool()[:3, 3]
    normal = front_normal(observer.points(frame, mask), grip, first.body_box, viewpoint(frame))
    return hinge_from_turn(state.axis.origin, state.handle.center, grip, state.handle.normal, normal,
                           MIN_SEEN_TURN_DEG, state.turn_hinge)


def _grip_path_axis(poses: np.ndarray, joint: JointType | None) -> AxisResult:
    """The axis fitted to the tool poses measured while pulling with the current grip (`EpisodeState.grip_start`;
    NoAxis before any pull was measured: the first one ran out of reach). A parallel gripper's fingers let the handle
    turn in them, so its own turn is not the door's: a hinge is fitted to the grip point's path alone (the turn still
    helps tell a hinge from a slide); NoAxis for one that cannot carry the path (`holds_path`)."""
    if len(poses) == 0:
        return NoAxis("no pull measured yet")
    turns = None if joint is JointType.REVOLUTE else Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    fitted = fit_trajectory(poses[:, :3, 3], turns, joint)
    if not holds_path(fitted, poses[:, :3, 3]):
        return NoAxis(f"the hinge fitted to the grip's path, {fitted.radius_m:.3f} m from it, is nearer than half "
                      "the path's extent: no such circle holds the path")
    return fitted


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
                          f"{episode.shown(state.opened):.3f}")
    if episode.now() > cfg.timeout_s:
        raise EpisodeStop(StopReason.TIMEOUT, f"{cfg.timeout_s:.0f} s of arm time used, opened "
                          f"{episode.shown(state.opened):.3f}")
    path, length, limits = _step_path(episode, axis)
    if axis.joint_type is JointType.PRISMATIC:
        _drawer_pull(episode, axis.direction, length, f"step {state.steps}: {source}", step=True)
        return
    label = f"step {state.steps}: {source}"
    try:
        _door_step(episode, axis, path, length, label, limits)
    except (IKError, EpisodeStop) as out_of_reach:
        if isinstance(out_of_reach, EpisodeStop) and out_of_reach.reason is not StopReason.IK_INFEASIBLE:
            raise
        _shorter_door_step(episode, axis, length, label, limits, out_of_reach)


def _door_step(episode: Episode, axis: Axis, path: PathFn, length: float, label: str, limits: MotionLimits) -> None:
    """A door's step; out of the arm's reach, its rest with the tool's orientation kept, or from a grasp with the
    hand turned back, where the handle allows."""
    try:
        checked_pull(episode, path, length, label, limits, step=True)
    except IKError as out_of_reach:
        if _turned_for_hand(episode, axis):
            _keep_orientation(episode, axis, length, label, limits)
        elif not _may_turn_back(episode, axis):
            raise
        else:
            regrasp_turned(episode, axis, out_of_reach)
    except EpisodeStop as stop:
        if stop.reason is not StopReason.BLOCKED or not _may_go_on_blocked(episode, axis):
            raise


def _shorter_door_step(episode: Episode, axis: Axis, length: float, label: str, limits: MotionLimits,
                       out_of_reach: IKError | EpisodeStop) -> None:
    """A door's step that nothing carries whole (`out_of_reach`) goes half as far, from where the arm stands with
    the tool turning as the step's would (each length checked before the arm moves), halved down to the goal's
    tolerance: the arm gets as near its reach's edge as it safely can, which may pass the target. Raises
    `out_of_reach` when no length is carried."""
    length /= 2
    while length >= GOAL_TOLERANCE[JointType.REVOLUTE]:
        path, _, _ = _step_path(episode, axis)
        try:
            checked_pull(episode, path, length, f"{label} (shortened)", limits, step=True)
            return
        except IKError:
            length /= 2
    raise out_of_reach


def _may_go_on_blocked(episode: Episode, axis: Axis) -> bool:
    """Whether a door's step that ended blocked may go on: it followed the hinge prior (no estimate acted on yet),
    the door pressed across its arc (`force_cue_n` or more: it went its own way, the prior is off), the gripper
    still holds it, few such steps went on (MAX_PRIOR_BLOCKS) and the front turned enough to place the hinge
    (`_hinge_seen_turning`), which the next estimate then acts on."""
    state = episode.state
    if axis.joint_type is not JointType.REVOLUTE or state.estimated or state.prior_blocks >= MAX_PRIOR_BLOCKS \
            or state.across_force_n < episode.config.opening.force_cue_n or not episode.gripping() \
            or state.handle is None or _hinge_seen_turning(episode) is None:
        return False
    state.prior_blocks += 1
    step_log.info("step %d blocked %.0f N across its arc about the hinge prior: the front turned otherwise, going on "
                  "about the hinge its turn shows", state.steps - 1, state.across_force_n)
    return True


def _turned_for_hand(episode: Episode, axis: Axis) -> bool:
    """Whether a door's step turns the tool with the door only to keep the front off the hand (`_step_path`): the
    handle held turns between the pads."""
    state = episode.state
    return axis.joint_type is JointType.REVOLUTE and not episode.policy.straight_door(axis.joint_type) \
        and state.handle is not None and not turns_with_door(episode.tool(), axis, state.handle.found)


def _keep_orientation(episode: Episode, axis: Axis, length: float, label: str, limits: MotionLimits) -> None:
    """A door's step that turned the tool with the door to keep the front off the hand ran out of the arm's reach:
    the rest of it keeps the tool's orientation (the handle turning between the pads), from where it stopped."""
    state = episode.state
    done = state.opened_before + opening(axis, state.p_grasp, episode.tool()[:3, 3]) - state.opened
    step_log.info("%s: turning the hand with the door is out of reach; the rest of the step keeps its orientation",
                  label)
    checked_pull(episode, arc_path(episode.tool(), axis.origin, axis.direction, turn=False), length - max(done, 0.0),
                 f"{label} (orientation kept)", limits, step=True)


def _may_turn_back(episode: Episode, axis: Axis) -> bool:
    """Whether a door's arc that ran out of reach may go on from a grasp with the hand turned back: the arc turns
    the tool with the door, the gripper still holds the handle and few such re-grasps were made."""
    state = episode.state
    return (axis.joint_type is JointType.REVOLUTE and not episode.policy.straight_door(axis.joint_type)
            and state.handle is not None and turns_with_door(episode.tool(), axis, state.handle.found)
            and episode.gripping() and state.turned_regrasps < MAX_TURNED_REGRASPS)


def _drawer_pull(episode: Episode, direction: np.ndarray, length: float, label: str, step: bool = False) -> None:
    """A straight pull along `direction` (a drawer's axis, or the front normal before any); when it runs out of the
    arm's reach with the gripper holding the handle, the arm takes the handle again from a configuration that carries
    the rest of the pull (`reseat`)."""
    try:
        checked_pull(episode, line_path(episode.tool(), direction), length, label, episode.line_limits(), step)
    except IKError as out_of_reach:
        state = episode.state
        if state.joint_type() is not JointType.PRISMATIC or not episode.gripping() or state.reseats >= MAX_RESEATS:
            raise
        reseat(episode, direction, out_of_reach)


# --- helpers ---------------------------------------------------------------------------------------------


def _grasp_plan(episode: Episode, handle: Handle) -> tuple[np.ndarray, float, np.ndarray]:
    """The grasp pose, how wide the fingers open for it and the pre-grasp joints: with a pointed part, the first
    grasp whose approach and first pull keep clear of the scene the first frame showed and that the arm carries
    (EpisodeStop when none keeps clear, IKError when the arm carries none); else the usual one, fully open. The
    grasps are tried in `_attempts`' order; each as found or turned half a turn about its approach
    (`pregrasp_either_way`)."""
    pointed, widest, kin = episode.observer.pointed, episode.gripper.max_opening_m, episode.kin
    approach, q = episode.config.opening.approach_m, episode.arm.state().q
    if pointed is None:
        grasps = [(grasp_pose(handle), widest if handle.open_m is None else handle.open_m, False)]
    else:
        scene = scene_tree(episode.observer.first_look.frame, pointed)
        grasps = ranked_grasps(handle, scene, lambda T: _planned_pulls(episode, handle, T), approach, widest)
    refused = None
    for (T, width), swung, whole in _attempts(grasps):
        try:
            T_held, q_pre = pregrasp_either_way(kin, q, T, lambda P: _planned_pulls(episode, handle, P), approach,
                                                swung, whole)
            return T_held, width, q_pre
        except IKError as e:
            refused = refused or e
    raise refused


def _attempts(grasps: list[tuple[np.ndarray, float, bool]]
              ) -> list[tuple[tuple[np.ndarray, float], bool, bool]]:
    """The (grasp, elbow swung out, whole pull only) tried, in order: the grasps that graze nothing (`ranked_grasps`),
    each with the arm's usual postures, then each with the elbow swung out sideways where that carries the whole
    planned pull; the grazing ones likewise; then every grasp swung out carrying any of its planned pulls. An
    unusual posture, sweeping more of the room on its way, is no better where a usual one carries a grasp as clear,
    and one that carries only part of the pull leaves the rest to a re-seat in it; but a hand resting on the
    scene (a counter's overhang above a thin drawer's bar) cannot centre the handle between its fingers."""
    tiers = [[(T, width) for T, width, grazes in grasps if bool(grazes) == tier] for tier in (False, True)]
    return [*((g, swung, swung) for tier in tiers for swung in (False, True) for g in tier),
            *(((T, width), True, False) for T, width, _ in grasps)]


def _planned_pulls(episode: Episode, handle: Handle, T_grasp: np.ndarray) -> list[list[np.ndarray]]:
    """The pulls the pre-grasp configuration is planned for, most wanted first: a door's arc about its likely
    hinge (`planned_door_arcs_deg`; the wrist turns with the door from the start), then straight out along the front
    normal, the drawer's whole pull (or PLANNED_DOOR_REACH_M for a door) and halves of it down to
    MIN_PLANNED_PULL_M."""
    pulls = []
    revolute = episode.state.joint is JointType.REVOLUTE
    if revolute and not episode.policy.straight_door(episode.state.joint):
        prior = _prior(episode, handle)
        pulls += [pull_poses(door_arc(T_grasp, prior, handle.found), np.radians(arc), PLANNED_ARC_STEP_RAD)
                  for arc in planned_door_arcs_deg(np.degrees(episode.goal(JointType.REVOLUTE)))]
    length = PLANNED_DOOR_REACH_M if revolute else \
        episode.config.opening.target_distance_m + OVERSHOOT[JointType.PRISMATIC]
    return pulls + line_pulls(T_grasp, handle.normal, length)


def planned_door_arcs_deg(goal_deg: float) -> tuple[float, ...]:
    """The door arcs a pre-grasp is planned for, most wanted first: the whole arc to the goal when it is longer than
    PLANNED_DOOR_ARCS_DEG's (a configuration that carries it spares the arm a joint limit late in the arc, where only
    letting go would help), then those."""
    return ((goal_deg,) if goal_deg > max(PLANNED_DOOR_ARCS_DEG, default=0.0) else ()) + PLANNED_DOOR_ARCS_DEG


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
    shown = episode.shown(state.opened)
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
    remaining = episode.goal(axis.joint_type) - state.opened
    size = episode.policy.step_size(axis.joint_type, state.steps, episode.config.opening)
    T = episode.tool()
    if axis.joint_type is JointType.PRISMATIC:
        return line_path(T, axis.direction), min(size, remaining), episode.line_limits()
    if episode.policy.straight_door(axis.joint_type):
        tangent = np.cross(axis.direction, T[:3, 3] - axis.origin)
        radius = max(float(np.linalg.norm(tangent)), 0.05)
        return line_path(T, tangent), min(size, remaining * radius), episode.line_limits()
    kind, arc = "" if state.handle is None else state.handle.found, min(size, remaining)
    turn = turns_with_door(T, axis, kind) or _door_meets_hand(episode, axis, arc)
    return arc_path(T, axis.origin, axis.direction, turn=turn), arc, episode.arc_limits()


def _door_meets_hand(episode: Episode, axis: Axis, arc: float) -> bool:
    """Whether the door (its front or the handle's bar) would reach into the hand by the end of an `arc` that keeps
    the tool's orientation (`door_meets_hand`; the handle's size and relief are the pointed front's): the arc then
    turns the tool with the door, so that the turn between them stays where it is. False without a pointed part."""
    state, pointed, arm = episode.state, episode.observer.pointed, episode.arm
    if pointed is None or state.handle is None:
        return False
    T_end = arc_path(episode.tool(), axis.origin, axis.direction, turn=False)(arc)
    hand = tuple(box for box in parallel_gripper(arm.state().gripper_width_m, episode.gripper.max_opening_m)
                 if box.name == "hand")  # the fingers straddle the handle, nearer than the front's place tells
    return door_meets_hand(T_end, state.handle, axis, state.opened + arc, pointed.handle.relief_m,
                           pointed.handle.length_m, hand)




