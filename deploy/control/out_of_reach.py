"""Pulls past the arm's reach: a drawer's handle taken again from another arm configuration (`reseat`), a door's
held again with the hand swung back toward the robot about it (`regrasp_turned`), a self-closing door kept held for
that swing (`_closing_push`, `_swing_held`); and the straight pulls a grasp is planned for (`line_pulls`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.control.context import GOAL_TOLERANCE, SETTLE_S, Episode
from deploy.control.door_regrasp import closing_push_n, door_plane, held_as, held_centre, opening_direction
from deploy.control.grasp import Handle, pregrasp_configuration, pull_poses
from deploy.control.hand import CLOSE_TIME_S, RETREAT_M, close_and_check, door_arc
from deploy.control.scene_clearance import Scene, clear_grasps, scene_tree
from deploy.control.state import EpisodeStop, StopReason
from deploy.control.view import step_log
from deploy.geometry.types import Axis, JointType
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
from drivers.arm.wrench import WrenchEstimator
from drivers.errors import IKError

MIN_PLANNED_PULL_M = 0.05  # straight pulls planned are halved down to this
PLANNED_LINE_STEP_M, PLANNED_ARC_STEP_RAD = 0.05, float(np.radians(5.0))  # planned pulls are checked this finely
DOOR_REGRASP_YAWS_DEG = (45.0, 30.0, 15.0)  # a door's arc out of reach: its handle is held again with the hand
# turned back toward the robot by the first of these (at most the door's turn so far) that keeps clear of the scene
# and of the door and that the arm carries
SELF_CLOSING_PROBE_RAD = float(np.radians(3.0))  # before letting a door go, the hand eases it this far back toward
# closed and carries it open again, feeling whether it pushes toward closed by itself
SELF_CLOSING_N = 2.0  # a door pushing its handle toward closed harder than this (four times the wrench's noise at
# rest) is self-closing: let go, it swings shut
HELD_SWING_SPEED_SHARE = 0.25  # the door's probe and a swing about a held handle move at this share of the arc's
# speed: the arm's own inertia stays out of the force felt, and the admittance keeps up with a pivot off the grip
SAME_GRASP_M, SAME_GRASP_RAD = 0.02, GRASP_PITCH_RAD / 2  # a grasp this near one the scene clearance passed is
# that one (half the turn between its tilted and level grasps)


def reseat(episode: Episode, direction: np.ndarray, out_of_reach: IKError) -> None:
    """The drawer's pull along `direction` ran out of the arm's reach (`out_of_reach`, a joint at its limit or a
    singularity): count the travel so far, open, back off along the approach, move to the pre-grasp joints that carry
    the rest of the pull from the same grasp (`pregrasp_configuration`), come back and close; later travel counts
    from the new grip. EpisodeStop("ik infeasible") when no configuration carries the rest."""
    arm, kin, state = episode.arm, episode.kin, episode.state
    T_hold = episode.tool()
    state.opened = state.opened_before + max(0.0, float((T_hold[:3, 3] - state.p_grasp) @ direction))
    rest = max(episode.goal(JointType.PRISMATIC) - state.opened, GOAL_TOLERANCE[JointType.PRISMATIC])
    try:
        q = pregrasp_configuration(kin, arm.state().q, T_hold, line_pulls(T_hold, direction, rest), RETREAT_M)
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
    _back_off(episode, T_hold)
    move_to_joints(arm, q, episode.joint_limits, episode.show_arm)
    episode.wait(SETTLE_S)
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), RETREAT_M, episode.line_limits(), episode.show_arm)
    close_and_check(episode, state.open_width_m, StopReason.GRASP_LOST, "re-grasp after the pull ran out of reach "
                    "failed: ")
    state.reseats += 1
    state.opened_before, state.p_grasp = state.opened, episode.tool()[:3, 3]


def _back_off(episode: Episode, T_hold: np.ndarray) -> None:
    """The open hand backs off the handle RETREAT_M along its approach: in a straight line, or, where the pose the
    pull lost its path at leaves no straight line (a singularity, a joint limit), by a joint move to the pose there
    (a few centimetres: the hand stays about on the line)."""
    arm, kin = episode.arm, episode.kin
    back = line_path(T_hold, -T_hold[:3, 2])
    try:
        follow_cartesian_path(arm, kin, back, RETREAT_M, episode.line_limits(), episode.show_arm)
    except IKError:
        move_to_pose(arm, kin, back(RETREAT_M), episode.joint_limits, episode.show_arm)


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
        raise EpisodeStop(StopReason.IK_INFEASIBLE, f"{out_of_reach}; at {episode.shown(state.opened):.0f} deg "
                          "the door's handle cannot be held again with the hand turned back toward the robot either "
                          "(no such grasp keeps clear of the scene and the door and carries the rest of the arc): "
                          "stand the robot nearer the door's hinge side or ask for a smaller opening")
    swing, yaw = plan
    push = _closing_push(episode, axis)
    if push is not None and push[0] > SELF_CLOSING_N:
        step_log.info("the arc is out of reach at %.1f deg (%s): the door pushes the handle toward closed with "
                      "%.1f N (friction %.1f N), so the hand stays closed on it and turns back %.0f deg about it",
                      episode.shown(state.opened), out_of_reach, *push, np.degrees(yaw))
        _swing_held(episode, swing, yaw, push[0])
    else:
        step_log.info("the arc is out of reach at %.1f deg (%s): holding the handle again with the hand turned back "
                      "%.0f deg", episode.shown(state.opened), out_of_reach, np.degrees(yaw))
        arm.set_gripper(state.open_width_m)
        episode.wait(CLOSE_TIME_S)
        open_width = arm.state().gripper_width_m
        T = episode.tool()
        episode.view.grasp(episode.now(), swing(T)(yaw))
        follow_cartesian_path(arm, episode.kin, swing(T), yaw, episode.arc_limits(), episode.show_arm)
        close_and_check(episode, open_width, StopReason.GRASP_LOST, "re-grasp with the hand turned back failed: ")
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
    as the pads turn about the handle (the arm then feels it across the fingers, as in `centre_on_handle`)."""
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
                          f"{episode.shown(state.opened):.0f} deg, and the door closes by itself (it pushes the "
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
    remaining = episode.goal(axis.joint_type) - state.opened
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


def line_pulls(T_grasp: np.ndarray, direction: np.ndarray, length: float) -> list[list[np.ndarray]]:
    """Straight pulls from the grasp pose along `direction`, `length` and halves of it down to MIN_PLANNED_PULL_M (or
    `length` alone when shorter), each as tool poses every PLANNED_LINE_STEP_M."""
    pulls = []
    while True:
        pulls.append(pull_poses(line_path(T_grasp, direction), length, PLANNED_LINE_STEP_M))
        if length <= MIN_PLANNED_PULL_M:
            return pulls
        length /= 2

