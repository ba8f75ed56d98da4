"""The hand on the handle: closing on it and checking the grip (one finger alone pressing it: centre it), easing off
a press before closing, the torque offset at rest, a pull with its checks (a slip re-grasps once, a block stops) and
the re-grasp after a slip; a door's arc as the hand follows it."""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.axis_pipeline import viewpoint
from deploy.control.context import MIN_GRASP_WIDTH_M, SETTLE_S, Episode
from deploy.control.grasp import (
    HALF_TURN,
    REGRASP_RADIUS_M,
    Handle,
    back_along_path,
    find_handle,
    grasp_pose,
    pointed_handle,
    protruding_points,
)
from deploy.control.policy import opening
from deploy.control.scene_clearance import GRIP_MARGIN_M
from deploy.control.state import EpisodeStop, StopReason
from deploy.errors import PointerError
from deploy.geometry.cloud import points_to_pixels
from deploy.geometry.types import Axis, JointType
from deploy.perception.base import Pointer
from deploy.perception.pointing import point_at
from drivers.arm.grasping import pregrasp_pose
from drivers.arm.motion import Outcome, PathFn, arc_path, follow_cartesian_path, line_path, move_to_pose
from drivers.arm.trajectory import MotionLimits
from drivers.arm.wrench import WrenchEstimator, torque_offset
from drivers.camera.base import Frame
from drivers.errors import ArmError

log = logging.getLogger(__name__)

CLOSE_TIME_S = 0.5
OPEN_MARGIN_M = 0.005  # a gripper within this of fully open did not close on anything
RETREAT_M = 0.05  # re-grasp: back off this far along the approach and come back
HINGE_ALIGNED_COS = float(np.cos(np.radians(20.0)))  # fingers closing within 20 deg of the hinge close "along" it:
# the door turning between the pads twists the handle in them by at most a third of its turn (sin 20 deg)
TURNING_HANDLES = ("edge pull", "cup", "bar")  # handles that may turn between the pads about the fingers' closing
ONE_FINGER_SHARE = 0.5  # closed, the arm feels more than this share of the grip force across the fingers: one finger
# alone presses the handle
CENTRING_STEP_M = 0.002  # such a handle is centred between the fingers in steps of this
PROBE_STEP_M = 0.004  # a handle the fingers closed wider than is looked for across them in steps of this: under a thin
# bar's half thickness (a step off a held bar leaves both fingers on it)
WIDTH_TOLERANCE_M = 0.001  # closed widths closer than this are one hold's (the pads' give, the handle's surface)
REST_READING_S = 0.1  # a force at rest is the mean of the readings over this long
PRESS_N = 10.0  # the approach ended with the tool pushing the handle this hard: ease back before closing
EASE_STEP_M, MAX_EASE_M = 0.004, 0.02  # easing back: step, and at most this far
MAX_SEAT_M = 0.014  # into a pocket the tool goes on at most this far: the calibration's error along the approach
# (5 mm, and 0.5 deg over the camera's metre or so: 9 mm)
SEAT_FORCE_N = 15.0  # ... pushing at most this hard
SEAT_SPEED_M_S = 0.01  # ... this slowly (the force bound stops it within a millimetre)
MISS_REACH_M = 0.04  # a gripper that closed on nothing goes on along its approach at most this far: a handle seen
# nearer than it stands (its front's plane taken from a counter's edge before it) lies between the open fingers,
# whose pads reach 5 cm past the palm


def checked_pull(episode: Episode, path: PathFn, length: float, label: str, limits: MotionLimits | None = None,
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


def regrasp(episode: Episode) -> None:
    """Open, back off along the approach, find the handle again in a fresh frame near where it was held or,
    released, gone back along the estimated path (a door swinging shut), approach it, ease off a press left at the
    approach's end (`ease_off_press`, as the first grasp does) and close. The opening is the one measured before the
    slipping pull (its share is not counted: the arm errs toward opening further), or less where the handle is found
    gone back; later travel counts from the new grip, and the grip's path fitted for the axis starts there (the
    fingers hold the handle at another point of it: they slid along it)."""
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
    T_grasp = held_way_round(grasp_pose(handle), T)
    episode.view.grasp(episode.now(), T_grasp)
    move_to_pose(arm, kin, pregrasp_pose(T_grasp, RETREAT_M), episode.joint_limits)
    episode.wait(SETTLE_S)
    T = episode.tool()
    follow_cartesian_path(arm, kin, line_path(T, T[:3, 2]), RETREAT_M, episode.line_limits(), episode.show_arm)
    ease_off_press(episode)
    close_and_check(episode, state.open_width_m, StopReason.GRASP_LOST, "re-grasp after a slip failed: ")
    p_new = episode.tool()[:3, 3]
    if state.axis is not None:
        state.opened = min(state.opened, state.opened_before + opening(state.axis, state.p_grasp, p_new))
    state.opened_before, state.p_grasp, state.grip_start = state.opened, p_new, len(state.measured)


def held_way_round(T_grasp: np.ndarray, T_tool: np.ndarray) -> np.ndarray:
    """`T_grasp`, or it turned half a turn about its approach, whichever turns the hand the less from `T_tool`: a
    parallel gripper holds a handle either way round, and the hand holds it again the way round its grasp was planned
    (`pregrasp_either_way` may have turned it to keep the wrist's last joint off its limit)."""
    def turn(T: np.ndarray) -> float:
        return Rotation.from_matrix(np.asarray(T_tool, float)[:3, :3].T @ T[:3, :3]).magnitude()

    turned = np.asarray(T_grasp, float) @ HALF_TURN
    return turned if turn(turned) < turn(T_grasp) else T_grasp


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


def measure_torque_offset(episode: Episode) -> None:
    """At the pre-grasp pose, touching nothing: the joint torques' own offset (motor-current torque sensing reads
    a few percent of each motor's peak torque there), the mean over SETTLE_S once the arm has settled, which every
    later force reading of the episode subtracts (`Compliance.torque_offset`)."""
    episode.wait(SETTLE_S)
    states = []
    for _ in range(round(SETTLE_S / episode.arm.control_period_s)):
        episode.arm.sync()
        states.append(episode.arm.state())
    episode.compliance = episode.compliance.with_torque_offset(torque_offset(episode.kin, states))


def ease_off_press(episode: Episode) -> None:
    """A handle nearer than seen (a short knob, the calibration's error) leaves the palm pushing on it at the
    approach's end. The first pull would start by releasing that push, which its force bound reads as resistance
    (a pull held still at 0 deg): back off along the approach until the tool no longer pushes. Arms that measure
    no joint torques skip this."""
    arm, kin = episode.arm, episode.kin
    wrench = WrenchEstimator(kin, 0.0, episode.compliance.torque_offset)
    for _ in range(round(MAX_EASE_M / EASE_STEP_M)):
        state = arm.state()
        w = wrench.update(state)
        T = kin.fk(state.q)
        if w is None or w[:3] @ T[:3, 2] < PRESS_N:
            return
        _step(episode, T, -T[:3, 2], EASE_STEP_M)
        episode.wait(SETTLE_S)


def close_and_check(episode: Episode, open_width: float, failure: StopReason, context: str = "") -> None:
    """Close on the handle; when one finger alone pressed it, centre it (`centre_on_handle`), open and close again
    so that both fingers squeeze it; when the fingers closed wider than the handle is thick without the arm feeling
    it, centre it by the closed width (`centre_by_width`), unless the part has opened: that probing opens the gripper
    at every step, and an opened part, let go, moves back (a self-closing spring) between the probes. EpisodeStop(
    `failure`) when the gripper closed on nothing."""
    width = _close(episode, open_width, failure, context)
    moved = centre_on_handle(episode, width)
    if moved:
        log.info("one finger alone pressed the handle (closed to %.1f mm): the tool moved %.1f mm toward it and "
                 "closed again", width * 1e3, moved * 1e3)
        episode.arm.set_gripper(open_width)
        episode.wait(CLOSE_TIME_S)
        width = _close(episode, open_width, failure, context)
    handle = episode.state.handle
    opened = episode.state.opened > 0.0
    if handle is not None and handle.thickness_m is not None and width > handle.thickness_m and not opened:
        moved = centre_by_width(episode, width, open_width)
        log.info("the fingers closed to %.1f mm on a %.1f mm handle: the tool moved %.1f mm across them to where "
                 "they close narrowest", width * 1e3, handle.thickness_m * 1e3, moved * 1e3)
        _close(episode, open_width, failure, context)


def close_or_reach(episode: Episode, open_width: float) -> None:
    """Close on the handle (`close_and_check`). When the fingers closed on nothing (a handle seen nearer than it
    stands lies beyond them), open them only as wide as the handle needs (its thickness and GRIP_MARGIN_M each side:
    a finger opened wide may stand on an overhang above a bar), go on along the approach, slowly (SEAT_SPEED_M_S, at
    most the approach's own speed), yielding and force-bounded at SEAT_FORCE_N (the front, or the handle, stops it),
    at most MISS_REACH_M; ease off the press left and close once more. EpisodeStop(GRASP_FAILED) when that misses
    too, when the tool could not go on (nothing lies farther to hold) or the arm carries no such move, or on an arm
    that measures no joint torques (no force bound)."""
    try:
        close_and_check(episode, open_width, StopReason.GRASP_FAILED)
        return
    except EpisodeStop as missed:
        state = episode.arm.state()
        if missed.reason is not StopReason.GRASP_FAILED or state.gripper_width_m > MIN_GRASP_WIDTH_M \
                or state.tau is None:
            raise
        handle = episode.state.handle
        if handle is not None and handle.thickness_m is not None:
            open_width = min(open_width, handle.thickness_m + 2 * GRIP_MARGIN_M)
        episode.arm.set_gripper(open_width)
        episode.wait(CLOSE_TIME_S)
        T = episode.tool()
        v = min(SEAT_SPEED_M_S, float(episode.line_limits().v_max))
        try:
            follow_cartesian_path(episode.arm, episode.kin, line_path(T, T[:3, 2]), MISS_REACH_M,
                                  MotionLimits(v, 4 * v, 40 * v), episode.show_arm,
                                  compliance=episode.compliance.with_force_limit(SEAT_FORCE_N))
        except ArmError:
            raise missed from None
        went = float((episode.tool()[:3, 3] - T[:3, 3]) @ T[:3, 2])
        if went < PROBE_STEP_M:
            raise
        log.info("the gripper closed on nothing: the tool went %.1f mm further along its approach", went * 1e3)
    ease_off_press(episode)
    close_and_check(episode, open_width, StopReason.GRASP_FAILED, "after going on along the approach: ")


def _close(episode: Episode, open_width: float, failure: StopReason, context: str) -> float:
    """Close the gripper; the width it stopped at. EpisodeStop(`failure`) when it closed on nothing."""
    episode.arm.set_gripper(0.0, episode.grip_force_n)
    episode.wait(CLOSE_TIME_S)
    width = episode.arm.state().gripper_width_m
    if not MIN_GRASP_WIDTH_M < width < open_width - OPEN_MARGIN_M:
        raise EpisodeStop(failure, f"{context}gripper closed to {width * 1e3:.1f} mm (open {open_width * 1e3:.1f} "
                          "mm): it missed the handle; check the handle detection and the camera calibration")
    return width


def centre_on_handle(episode: Episode, width: float) -> float:
    """How far (m) the tool moved to centre the handle between the closed fingers. Each finger closes to the
    gripper's middle: a handle lying off it by more than half its thickness stops one finger while the other closes
    short of it, and the arm then feels that finger's squeeze across the fingers (the tool pushes the handle toward
    the middle). Still squeezing, the tool moves toward the touching finger in CENTRING_STEP_M steps until the other
    finger presses too (the force across them drops), at most the closed `width` (the touching finger is no farther
    from the middle). Arms that measure no joint torques do not move."""
    moved = 0.0
    while moved < width:
        force, T = _force_at_rest(episode)
        across = 0.0 if force is None else float(force @ T[:3, 1])
        if abs(across) < ONE_FINGER_SHARE * episode.grip_force_n:
            break
        _step(episode, T, -np.sign(across) * T[:3, 1], CENTRING_STEP_M)
        moved += CENTRING_STEP_M
    return moved


def centre_by_width(episode: Episode, width: float, open_width: float) -> float:
    """How far (m, signed along the fingers' closing axis) the tool moved to where the closed fingers hold the handle
    narrowest. A handle off the fingers' middle by more than half its thickness stops one finger while the other
    closes past it to the middle: the closed width then exceeds the handle's thickness by its offset (by twice it on
    a gripper whose fingers move together), and shrinks as the tool moves toward it, down to the handle's thickness
    once both fingers hold it. Some grippers' fingers barely press what stops one of them (the arm then feels
    nothing across them: `centre_on_handle` does not move): the tool tries a PROBE_STEP_M step either way (open,
    step, close), goes on the way the width shrank (by more than WIDTH_TOLERANCE_M) while it does, at most the closed
    `width` (the touching finger is no farther from the middle), and ends closed where it last shrank at all (the
    step that brings the free finger onto it shrinks it by less than a step; where it was, when it shrank neither
    way)."""
    T0 = episode.tool()
    widths = {0.0: width}
    direction = 0.0
    for sign in (1.0, -1.0):
        at = offset = sign * PROBE_STEP_M
        widths[at] = _closed_at(episode, T0, at, open_width)
        if widths[at] < width - WIDTH_TOLERANCE_M:
            direction = sign
            break
    while direction and abs(offset) + PROBE_STEP_M <= width:
        at = offset + direction * PROBE_STEP_M
        widths[at] = _closed_at(episode, T0, at, open_width)
        if widths[at] >= widths[offset] - WIDTH_TOLERANCE_M:
            break
        offset = at
    if direction and widths[at] < widths[offset]:  # the last step brought the free finger onto it
        offset = at
    best = offset if direction else 0.0
    if best != at:
        _closed_at(episode, T0, best, open_width)
    return best


def _closed_at(episode: Episode, T0: np.ndarray, offset: float, open_width: float) -> float:
    """Open the gripper, move the tool to `offset` (m) along the fingers' closing axis from pose T0, close; the width
    it closed to (infinite when it closed on nothing)."""
    episode.arm.set_gripper(open_width)
    episode.wait(CLOSE_TIME_S)
    T = episode.tool()
    target = T0[:3, 3] + offset * T0[:3, 1]
    shift = target - T[:3, 3]
    if np.linalg.norm(shift) > 1e-4:
        _step(episode, T, shift / np.linalg.norm(shift), float(np.linalg.norm(shift)))
    episode.arm.set_gripper(0.0, episode.grip_force_n)
    episode.wait(CLOSE_TIME_S)
    width = episode.arm.state().gripper_width_m
    return width if MIN_GRASP_WIDTH_M < width < open_width - OPEN_MARGIN_M else float("inf")


def seat_in_pocket(episode: Episode) -> bool:
    """Whether the tool went on into a recessed pull's pocket. Its fingers, open around the bar, fill most of the
    pocket's height; an approach that ends with a push mostly across them has a finger on the pocket's lip, short
    of the bar by the calibration's error along the approach (the pocket's mouth is seen, not its bar), and easing
    off would draw the fingers farther off it. The tool then goes on along the approach, slowly (SEAT_SPEED_M_S), at
    most MAX_SEAT_M, force-bounded at SEAT_FORCE_N (the front, or the pocket's back, stops it) and yielding across
    to what pushes it there. Otherwise (nothing pushes, or the palm presses the front) it stays for the usual
    easing off. Arms that measure no joint torques do not move."""
    state = episode.arm.state()
    w = WrenchEstimator(episode.kin, 0.0, episode.compliance.torque_offset).update(state)
    if w is None:
        return False
    T = episode.kin.fk(state.q)
    along, across = float(w[:3] @ T[:3, 2]), abs(float(w[:3] @ T[:3, 1]))
    if across < PRESS_N or along >= across:
        return False
    limits = MotionLimits(SEAT_SPEED_M_S, 4 * SEAT_SPEED_M_S, 40 * SEAT_SPEED_M_S)
    result = follow_cartesian_path(episode.arm, episode.kin, line_path(T, T[:3, 2]), MAX_SEAT_M, limits,
                                   episode.show_arm, compliance=episode.compliance.with_force_limit(SEAT_FORCE_N))
    log.info("a finger on the pocket's lip: the tool went %.1f mm further in (%s)",
             float(np.linalg.norm(episode.tool()[:3, 3] - T[:3, 3])) * 1e3, result.reason)
    return True


def _force_at_rest(episode: Episode) -> tuple[np.ndarray | None, np.ndarray]:
    """The force the tool exerts (base frame; the mean over REST_READING_S, None for an arm that measures no joint
    torques) and the tool pose."""
    arm = episode.arm
    wrench = WrenchEstimator(episode.kin, 0.0, episode.compliance.torque_offset)
    states = []
    for _ in range(round(REST_READING_S / arm.control_period_s)):
        arm.sync()
        states.append(arm.state())
    w = wrench.start(states)
    return (None if w is None else w[:3]), episode.kin.fk(states[-1].q)


def _step(episode: Episode, T: np.ndarray, direction: np.ndarray, length: float) -> None:
    """A short straight move of the tool from pose T along `direction`."""
    follow_cartesian_path(episode.arm, episode.kin, line_path(T, direction), length, episode.line_limits(),
                          episode.show_arm)


def door_arc(T: np.ndarray, axis: Axis, kind: str) -> PathFn:
    """The tool's arc about a door's axis from pose T, holding a handle of `kind` (`Handle.found`). Fingers closing
    along the hinge across a horizontal handle that lies along their pads (TURNING_HANDLES: a tab, a cup, a bar) let
    it turn between the pads as the door swings: the tool keeps its orientation, sparing the wrist the door's turn.
    Otherwise the tool turns with the door: a vertical bar (the hand's width lies in the swing), a knob (its stem
    would swing into the fingers), a pocket (its walls would)."""
    return arc_path(T, axis.origin, axis.direction, turn=turns_with_door(T, axis, kind))


def turns_with_door(T: np.ndarray, axis: Axis, kind: str) -> bool:
    """Whether the tool at pose T holding a handle of `kind` turns with the door (`door_arc`)."""
    along_hinge = abs(float(T[:3, 1] @ axis.direction)) >= HINGE_ALIGNED_COS
    return not (along_hinge and kind in TURNING_HANDLES)

