"""Scripted openings that use the simulator's GROUND TRUTH: a data generator, NOT the opening policy.

The script reads the true handle pose and joint axis from the world, grasps the handle and pulls along
the true line or arc. Use it to make recordings with known axes (`deploy sim record`) and to benchmark
the simulation; the policy must only ever see the camera and the arm.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pybullet as pb

from drivers.arm.base import ArmState
from drivers.arm.grasping import FROM_ABOVE_RAD, GRASP_DEPTH_M, GRASP_PITCH_RAD, LIMIT_MARGIN_RAD, pregrasp_pose
from drivers.arm.grasping import grasp_pose as bar_grasp_pose
from drivers.arm.kinematics import Kinematics, well_conditioned_start
from drivers.arm.motion import (
    OnTick,
    PathFn,
    PathResult,
    arc_path,
    follow_cartesian_path,
    line_path,
    move_to_joints,
)
from drivers.arm.robot_config import panda_sim_config
from drivers.arm.trajectory import MotionLimits
from drivers.camera.base import SegLabel
from drivers.camera.frames_dir import FramesWriter
from drivers.errors import ArmError
from sim_fallback.arm import SimArm
from sim_fallback.cabinet_urdf import Kind, Split
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.kitchen_scenario import KitchenScenario, recording_camera
from sim_fallback.scenario import Scenario
from sim_fallback.scenes import scenario_object, scene_scenario
from sim_fallback.start import Q_START
from sim_fallback.world import JointTruth, SimWorld

log = logging.getLogger(__name__)

PREGRASP_M = 0.10  # straight approach along the gripper's axis over the last 10 cm
FINGERTIPS_PAST_TOOL_M = 0.011  # the Panda's fingertips reach this far past its grasp frame
FINGERTIP_CLEARANCE_M = 0.003
PREGRASP_MARGIN_M = 0.015  # the open fingers clear the handle by this much each side
CLOSE_TIME_S = 0.5
DEFAULT_TARGET = {"drawer": 0.20, "door": float(np.radians(30.0))}  # m, rad
GRASPS = ((GRASP_PITCH_RAD, False), *((p, False) for p in FROM_ABOVE_RAD), (0.0, False), (-GRASP_PITCH_RAD, False),
          *((p, True) for p in (GRASP_PITCH_RAD, 0.0, -GRASP_PITCH_RAD)))  # (pitch, elbow swung out) tried in turn:
# the usual grasp, from above (a low handle), level and tilted up (a bar under an overhang), then the elbow swung out
APPROACH_CHECKS = 5  # the hand is checked clear at this many poses along its straight approach
APPROACH_LIMITS = MotionLimits(0.10, 0.5, 5.0)  # m/s, m/s^2, m/s^3 along the approach line
OPENED_SHARE = 0.5  # a recording whose part opened less than this share of the target is refused (kept on disk)
OPEN_LIMITS = {"drawer": MotionLimits(0.10, 0.3, 3.0), "door": MotionLimits(0.25, 0.6, 6.0)}  # m or rad


def grasp_pose(world: SimWorld, pitch_rad: float = GRASP_PITCH_RAD) -> np.ndarray:
    """Tool pose grasping the target part's true handle from the front tilted down by `pitch_rad`, fingers across its
    bar (base frame), as deep as its handle leaves room for: the fingertips stop FINGERTIP_CLEARANCE_M short of the
    surface behind it."""
    centre, bar, normal = world.target_handle()
    handle = world.target.part.handle
    depth = GRASP_DEPTH_M
    if handle is not None and handle.clear_behind_m is not None:
        depth = min(depth, handle.clear_behind_m - FINGERTIPS_PAST_TOOL_M - FINGERTIP_CLEARANCE_M)
    return bar_grasp_pose(centre, normal, bar, depth_m=depth, pitch_rad=pitch_rad)


def pregrasp_width(world: SimWorld) -> float:
    """How wide the gripper opens before it closes on the target's handle: its thickness and a margin each side
    (room in a recessed pull's pocket), at most the gripper's width."""
    handle = world.target.part.handle
    widest = world.robot_spec.gripper_max_width_m
    return widest if handle is None else min(widest, handle.thickness_m + 2 * PREGRASP_MARGIN_M)


def opening_path(T_start: np.ndarray, truth: JointTruth) -> PathFn:
    """Tool poses opening the joint by s (m or rad) from `T_start` along the TRUE axis."""
    if truth.joint_type == "prismatic":
        return line_path(T_start, truth.direction)
    return arc_path(T_start, truth.origin, truth.direction)


def pregrasp_configuration(kin: Kinematics, world: SimWorld, length: float) -> tuple[np.ndarray, np.ndarray]:
    """(grasp pose, joint positions at its pre-grasp pose) of the first grasp of GRASPS from which the approach and
    the opening path along the true axis stay clear of joint limits (the seed farthest from singularities: largest
    smallest singular value of the Jacobian along them; the Panda is redundant and per-tick IK near a singularity
    spins joints 1 and 3) and whose hand meets nothing around the furniture along its approach (`hand_clear`); when
    every such grasp meets something, the first of them."""
    truth, width, first = world.truth(), pregrasp_width(world), None
    for pitch, swung in GRASPS:
        T_grasp = grasp_pose(world, pitch)
        opening = opening_path(T_grasp, truth)
        poses = [pregrasp_pose(T_grasp, PREGRASP_M), T_grasp, *(opening(s) for s in np.linspace(0.0, length, 12)[1:])]
        best = well_conditioned_start(kin, poses, Q_START, LIMIT_MARGIN_RAD, swung=swung)
        if best is None:
            continue
        approach = [pregrasp_pose(T_grasp, d) for d in np.linspace(PREGRASP_M, 0.0, APPROACH_CHECKS)]
        if hand_clear(world, kin.solve_path(approach, best, restarts=0), width):
            return T_grasp, best
        first = first or (T_grasp, best)
    if first is not None:
        return first
    raise ArmError(f"scripted grasp: no arm configuration reaches the handle and follows the opening "
                   f"by {length:.3f} (m or rad) clear of joint limits and singularities, whether from the front or "
                   "from above; try another seed or a smaller target")


def hand_clear(world: SimWorld, qs: np.ndarray, width_m: float) -> bool:
    """Whether the hand (the robot's links past its last arm joint), its fingers open `width_m`, meets nothing around
    the target's furniture at each of the arm's joint positions `qs`: no other furniture, counter, wall or object.
    The furniture's own frame and fronts beside the handle it may brush, at any pitch. Ground truth; the joints are
    put back as they were."""
    c, robot, spec = world.client, world.robot_id, world.robot_spec
    joints = [world.robot_joints[name] for name in (*spec.arm_joints, *spec.finger_joints)]
    held = [pb.getJointState(robot, j, physicsClientId=c)[:2] for j in joints]
    hand = range(world.robot_joints[spec.arm_joints[-1]] + 1, pb.getNumJoints(robot, physicsClientId=c))
    around = [b for b in (pb.getBodyUniqueId(k, physicsClientId=c) for k in range(pb.getNumBodies(physicsClientId=c)))
              if b not in (robot, world.truth().body_id)]
    try:
        for q in qs:
            for j, value in zip(joints, [*q, *spec.finger_positions(width_m)], strict=True):
                pb.resetJointState(robot, j, float(value), physicsClientId=c)
            if any(pb.getClosestPoints(robot, body, 0.0, link, physicsClientId=c) for body in around for link in hand):
                return False
        return True
    finally:
        for j, (q, dq) in zip(joints, held, strict=True):
            pb.resetJointState(robot, j, q, dq, physicsClientId=c)


def grasp_handle(
    world: SimWorld, arm: SimArm, limits: MotionLimits, target: float, on_tick: OnTick | None = None
) -> None:
    """Move to the pre-grasp pose, approach along the gripper axis and close on the handle (ground truth).
    `target` is the opening that follows, used to pick an arm configuration that can make it. ArmError when no arm
    configuration makes it, or when the fingers closed on something else than the handle."""
    T_grasp, q_pre = pregrasp_configuration(arm.kin, world, target)
    arm.set_gripper(pregrasp_width(world))
    move_to_joints(arm, q_pre, limits, on_tick)
    approach = T_grasp[:3, 2]
    follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), approach), PREGRASP_M,
                          APPROACH_LIMITS, on_tick)
    arm.set_gripper(0.0, panda_sim_config().grip_force_n)
    wait(arm, CLOSE_TIME_S, on_tick)
    if not holds_target(world):
        style = world.target.part.handle.style if world.target.part.handle is not None else "unmarked"
        raise ArmError(f"scripted grasp: the fingers did not both close on the {style} handle of the "
                       f"{world.target.part.name}: the hand met something else first; try another seed or part")


def holds_target(world: SimWorld) -> bool:
    """Whether both fingers touch the target part (its link or its handle's)."""
    c, links = world.client, world.truth().links
    fingers = [world.robot_joints[name] for name in world.robot_spec.finger_joints]
    return all(any(pb.getContactPoints(world.robot_id, world.cabinet_id, f, link, physicsClientId=c) for link in links)
               for f in fingers)


def open_along_truth(
    world: SimWorld, arm: SimArm, target: float, limits: MotionLimits, on_tick: OnTick | None = None
) -> PathResult:
    """Pull the grasped handle open by `target` (m or rad) along the true line or arc."""
    T_start = arm.kin.fk(arm.state().q)
    return follow_cartesian_path(arm, arm.kin, opening_path(T_start, world.truth()), target, limits, on_tick)


def wait(arm: SimArm, duration_s: float, on_tick: OnTick | None = None) -> None:
    """Let `duration_s` of simulated time pass with the arm holding its last command."""
    t0 = arm.time()
    for _ in range(int(round(duration_s / arm.control_period_s))):
        arm.sync()
        if on_tick is not None:
            on_tick(arm.state(), arm.time() - t0)


@dataclass(frozen=True)
class RecordingSummary:
    """What a scripted recording produced: joint values in m (drawer) or rad (door)."""

    path: Path
    task: Kind
    seed: int
    split: Split
    world: str
    part: str
    frames: int
    joint_start: float
    joint_end: float
    target: float
    sim_time_s: float
    wall_time_s: float

    def __str__(self) -> str:
        scale, unit = (100.0, "cm") if self.task == "drawer" else (float(np.degrees(1.0)), "deg")
        return (f"{self.frames} frames, {self.part} ({self.world}) opened {self.joint_end * scale:.1f} of "
                f"{self.target * scale:.1f} {unit} in {self.sim_time_s:.1f} s simulated "
                f"({self.wall_time_s:.1f} s wall)")


def _filmed(scenario: Scenario | KitchenScenario) -> Scenario | KitchenScenario:
    """The scenario with a kitchen's camera set up to film its part (`recording_camera`)."""
    return replace(scenario, camera=recording_camera(scenario)) if isinstance(scenario, KitchenScenario) else scenario


def record_scripted(
    task: Kind | None,
    seed: int,
    out_dir: str | Path,
    split: Split = "train",
    target: float | None = None,
    fps: float = 10.0,
    resolution: tuple[int, int] = (640, 480),
    progress: Callable[[str, int], None] | None = None,
    world: str = "kitchen",
    part: str | None = None,
    assets: Path | None = None,
    object_id: str | None = None,
    scale: str = "real",
) -> RecordingSummary:
    """Record a scripted opening of scenario `seed` of `world` ("kitchen", or "box": one cabinet in empty space) with
    `part` its target part as a user names it (default the seed's), in a kitchen the PartNet-Mobility object
    `object_id` of `assets` at `scale` when given (sim_fallback.scenes; task None: the object's), driven by GROUND
    TRUTH (a data generator, not the policy).

    Writes the frames-directory format at `out_dir` (colour, noisy depth, object mask including the
    handle, T_base_camera, joint positions, tool pose and `grasped` per frame: false over the approach until the
    gripper has closed on the handle, true from then on) plus truth.json with the true joint type, axis (base
    frame; positive opens), the joint value at every frame, the world and the part. `target`: opening in m (drawer,
    default 0.2) or rad (door, default 30 deg), which the robot is parked to make. progress(phase, frames) follows
    every frame written (phase: "grasp", "open" or "hold").
    """
    out = Path(out_dir)
    wall0 = time.perf_counter()
    task = task or scene_scenario(world, task, seed, split, part, assets, object_id, scale).task  # the object's
    target = DEFAULT_TARGET[task] if target is None else float(target)
    scenario = _filmed(scene_scenario(world, task, seed, split, part, assets, object_id, scale, opening=target))
    log.info("scripted %s opening from GROUND TRUTH (data generator, not the policy): %s seed %d, split %s, %s",
             task, world, seed, split, scenario_object(scenario))
    with SimWorld(scenario) as sim:
        arm = SimArm(sim)
        camera = SimCamera(sim, intrinsics=d415_intrinsics(*resolution), seed=seed, fps=fps, labels=True, posed=True)
        limits = panda_sim_config().motion_limits(arm.kin, 0.3)
        joint_values: list[float] = []
        with FramesWriter(out, camera.intrinsics, T_base_camera=camera.T_base_camera, camera="sim",
                          simulated=True) as writer:
            next_t, phase = 0.0, "grasp"

            def capture(state: ArmState, _t: float = 0.0) -> None:
                nonlocal next_t
                if state.t < next_t - 1e-9:
                    return
                frame = camera.read()
                mask = (frame.segmentation == SegLabel.OBJECT) | (frame.segmentation == SegLabel.HANDLE)
                writer.write(frame, mask=mask, joint_positions=state.q, ee_pose=arm.kin.fk(state.q),
                             grasped=phase != "grasp")
                joint_values.append(sim.joint_value())
                next_t = (frame.index + 1) / fps
                if progress is not None:
                    progress(phase, len(joint_values))

            capture(arm.state())
            grasp_handle(sim, arm, limits, target, capture)
            phase = "open"  # the gripper has closed on the handle: it holds from here on
            open_along_truth(sim, arm, target, OPEN_LIMITS[task], capture)
            phase = "hold"
            wait(arm, 0.5, capture)
        truth = sim.truth()
        (out / "truth.json").write_text(json.dumps({
            "source": "simulator ground truth (scripted data generator)",
            "task": task, "seed": seed, "split": split, "world": world, "part": truth.part,
            "furniture": scenario_object(scenario), "assets": None if assets is None else str(assets),
            "object": object_id, "scale": scale if assets is not None else None, "target": target,
            "joint_type": truth.joint_type,
            "origin": truth.origin.tolist(), "direction": truth.direction.tolist(),
            "joint_upper": truth.upper, "joint_values": joint_values,
        }, indent=2) + "\n")
        summary = RecordingSummary(out, task, seed, split, world, truth.part, len(joint_values), joint_values[0],
                                   joint_values[-1], target, sim.time, time.perf_counter() - wall0)
    log.info("recorded %s: %s", out, summary)
    if abs(summary.joint_end - summary.joint_start) < OPENED_SHARE * target:
        raise ArmError(f"scripted opening: {summary}: the hand followed the true path but the part stayed (its catch, "
                       f"friction or spring outheld the grip); the frames are kept in {out}: try another seed or part")
    return summary
