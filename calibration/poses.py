"""Calibration stations: diverse tool poses around a start pose, reachable and clear of the joint limits.

Every pose turns the tool about a pivot fixed in the tool frame, so that the pivot stays where it was:
put the pivot at the board's centre (eye-to-hand, board on the tool) or at the point the wrist camera
looks at (eye-in-hand), and the board stays in view while the rotations vary. The tilt axes step by the
golden angle, so consecutive rotations are about non-parallel axes; each pose also rolls about the
tool's z axis and shifts by a few centimetres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.arm.kinematics import Kinematics
from drivers.errors import ArmError, CalibrationError

GOLDEN_ANGLE_RAD = np.pi * (3 - np.sqrt(5))
CANDIDATES_PER_POSE = 4  # unreachable candidates are skipped; give up after this many per requested pose


@dataclass(frozen=True)
class PoseConfig:
    """Station generator: tilt (deg) about axes in the tool's xy plane, roll (deg) about its z axis, shift (m)
    of the pivot, pivot (m) in the tool frame, joint-limit margin (rad) and the random seed."""

    tilt_deg: tuple[float, float] = (12.0, 28.0)
    roll_deg: float = 30.0
    shift_m: float = 0.04
    pivot_tool_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint_margin_rad: float = 0.15
    seed: int = 0


def intrinsics_stations(pivot_tool_m: tuple[float, float, float], seed: int = 0) -> PoseConfig:
    """Stations for intrinsics: steeper tilts (20-40 deg) to fix the focal length and larger shifts (10 cm) to
    spread the board over the image; hand-eye's gentler defaults leave fx uncertain by 1-1.5 %."""
    return PoseConfig(tilt_deg=(20.0, 40.0), shift_m=0.10, pivot_tool_m=pivot_tool_m, seed=seed)


def candidate_poses(T_start: np.ndarray, n: int, cfg: PoseConfig) -> list[np.ndarray]:
    """`n` tool poses (4x4, base frame) around T_start, deterministic for a given seed."""
    rng = np.random.default_rng(cfg.seed)
    pivot = np.asarray(cfg.pivot_tool_m, float)
    p_pivot = T_start[:3, :3] @ pivot + T_start[:3, 3]
    poses = []
    for k in range(n):
        phi = k * GOLDEN_ANGLE_RAD
        tilt = np.radians(rng.uniform(*cfg.tilt_deg))
        roll = np.radians(rng.uniform(-cfg.roll_deg, cfg.roll_deg))
        tilt_axis = np.array([np.cos(phi), np.sin(phi), 0.0])
        R_rel = (Rotation.from_rotvec([0.0, 0.0, roll]) * Rotation.from_rotvec(tilt * tilt_axis)).as_matrix()
        T = np.eye(4)
        T[:3, :3] = T_start[:3, :3] @ R_rel
        T[:3, 3] = p_pivot - T[:3, :3] @ pivot + rng.uniform(-cfg.shift_m, cfg.shift_m, 3)
        poses.append(T)
    return poses


def plan_stations(kin: Kinematics, q_start: np.ndarray, n: int, cfg: PoseConfig,
                  workspace: tuple[np.ndarray, np.ndarray] | None = None) -> list[np.ndarray]:
    """Joint positions of `n` stations around the tool pose at q_start: each reachable by IK near the start
    joints (or else near the previous station's), `joint_margin_rad` inside the limits and (if given) inside the
    workspace box (min, max).
    Raises CalibrationError when fewer than n are found."""
    T_start = kin.fk(q_start)
    q_min, q_max = kin.q_min + cfg.joint_margin_rad, kin.q_max - cfg.joint_margin_rad
    stations: list[np.ndarray] = []
    q = np.asarray(q_start, float)
    for T in candidate_poses(T_start, n * CANDIDATES_PER_POSE, cfg):
        if len(stations) == n:
            break
        if workspace is not None and (np.any(T[:3, 3] < workspace[0]) or np.any(T[:3, 3] > workspace[1])):
            continue
        q_next = _ik_near(kin, T, (np.asarray(q_start, float), q))
        if q_next is not None and np.all(q_next >= q_min) and np.all(q_next <= q_max):
            stations.append(q_next)
            q = q_next
    if len(stations) < n:
        raise CalibrationError(
            f"only {len(stations)} of {n} calibration poses are reachable around the start pose: start from a "
            "pose nearer the middle of the arm's workspace, or lower --poses or the tilt range"
        )
    return stations


def _ik_near(kin: Kinematics, T: np.ndarray, seeds: tuple[np.ndarray, ...]) -> np.ndarray | None:
    """IK for T from the first seed that converges (no random restarts: stay on the seeds' branch)."""
    for seed in seeds:
        try:
            return kin.ik(T, seed, q_rest=seeds[0], restarts=0)
        except ArmError:
            continue
    return None
