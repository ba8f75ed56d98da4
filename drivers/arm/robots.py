"""Robot models: where each arm's URDF lives, its joints, tool frame, ready pose and hardware limits."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pybullet_data


@dataclass(frozen=True)
class Reach:
    """Where an arm grasps a handle and pulls it comfortably, in its base frame (m): per task, the grip's horizontal
    distance from the base and its height above the base. Simulated scenes park the robot so that the target's grip
    falls in these bands, as a user parks an arm in front of what it must open (`scripts/reach_scan.py` maps an
    arm's). The defaults are the Panda's: a 45 cm drawer pull and a door's swing stay clear of its joint limits.

    `drawer_pull_m`: the pull the drawer bands are set for; a drawer pulled less is grasped the usual way lower down
    where the arm's kinematics carry the shorter pull (sim_fallback/kitchen_scenario.py `short_pull_reach`).

    `low_*`: the bands where the arm grasps a low handle from above (the approach tilted steeply down) and pulls it,
    for furniture with no part in the usual bands (None: the arm has none measured for that task). `model`: the robot
    config (a shipped name or a TOML file) whose kinematics a scene's parking is checked with, as a user tries the arm
    there: a band's corner can lie past the arm's reach (None: the bands alone)."""

    drawer_distance_m: tuple[float, float] = (0.55, 0.68)
    drawer_height_m: tuple[float, float] = (0.72, 0.86)
    door_distance_m: tuple[float, float] = (0.5, 0.85)
    door_height_m: tuple[float, float] = (0.62, 0.78)
    drawer_pull_m: float = 0.45
    low_drawer_distance_m: tuple[float, float] | None = None
    low_drawer_height_m: tuple[float, float] | None = None
    low_door_distance_m: tuple[float, float] | None = None
    low_door_height_m: tuple[float, float] | None = None
    model: str | None = None

    def distance(self, task: str) -> tuple[float, float]:
        return self.drawer_distance_m if task == "drawer" else self.door_distance_m

    def height(self, task: str) -> tuple[float, float]:
        return self.drawer_height_m if task == "drawer" else self.door_height_m

    def from_above(self, task: str) -> Reach | None:
        """The reach whose `task` bands are this arm's from above (its low ones); None when it has none."""
        distance, height = ((self.low_drawer_distance_m, self.low_drawer_height_m) if task == "drawer" else
                            (self.low_door_distance_m, self.low_door_height_m))
        if distance is None or height is None:
            return None
        return replace(self, **{f"{task}_distance_m": distance, f"{task}_height_m": height})

    def usual(self) -> Reach:
        """This reach without its bands from above, its drawer bands serving every pull (none lowered for a short
        one)."""
        return replace(self, low_drawer_distance_m=None, low_drawer_height_m=None, low_door_distance_m=None,
                       low_door_height_m=None, drawer_pull_m=0.0)


# The Panda's, from above: a low bar grasped with the approach tilted 0.7 or 1.1 rad down (drivers/arm/
# grasping.py FROM_ABOVE_RAD), a drawer's pulled 45 cm and a door's swung 45 deg (drivers/arm/configs/
# panda_sim.toml says the same, with the scans).
PANDA_REACH = Reach(low_drawer_distance_m=(0.70, 0.75), low_drawer_height_m=(0.40, 0.70),
                    low_door_distance_m=(0.60, 0.75), low_door_height_m=(0.25, 0.62), model="panda_sim")


@dataclass(frozen=True)
class RobotSpec:
    """What the kinematics, safety and motion code need to know about one arm model.

    `tool_frame` is the URDF frame the grasp is planned for; `q_ready` (rad) holds the hand
    forward-horizontal in front of the robot; `a_max` (rad/s^2) and `j_max` (rad/s^3) are the
    per-joint hardware limits (velocity limits come from the URDF); the workspace box bounds the
    tool position in the base frame (m). `finger_joint_per_m`: each finger joint's value (m or rad) per metre of
    gripper opening (two prismatic fingers: 0.5 each; hinged fingers: their angle, linearised). `q_start` (rad):
    where the arm starts in simulated scenes, around which they jitter it (None: q_ready). `reach`: where simulated
    scenes put the target's grip.
    """

    name: str
    urdf: Path
    arm_joints: tuple[str, ...]
    finger_joints: tuple[str, ...]
    tool_frame: str
    q_ready: np.ndarray
    gripper_max_width_m: float
    a_max: np.ndarray
    j_max: np.ndarray
    workspace_min: np.ndarray
    workspace_max: np.ndarray
    finger_joint_per_m: tuple[float, ...] = (0.5, 0.5)
    q_start: np.ndarray | None = None
    reach: Reach = PANDA_REACH

    @property
    def start(self) -> np.ndarray:
        """The simulated scenes' start configuration (q_start, else q_ready)."""
        return self.q_ready if self.q_start is None else self.q_start

    def finger_positions(self, width_m: float) -> list[float]:
        """The finger joints' values at gripper opening `width_m`."""
        return [k * width_m for k in self.finger_joint_per_m]

    def gripper_width(self, finger_positions) -> float:
        """The gripper opening (m) the finger joints' values read (their mean)."""
        return float(sum(q / k for q, k in zip(finger_positions, self.finger_joint_per_m, strict=True))
                     / len(self.finger_joint_per_m))


def panda_urdf() -> Path:
    """The Franka Panda URDF shipped with pybullet_data."""
    return Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"


def panda() -> RobotSpec:
    """Franka Panda: 7 arm joints, two mimicking fingers, grasp frame `panda_grasptarget`.

    `panda_grasptarget` is the URDF's fixed frame between the fingertips, 0.105 m along the hand's
    z axis. At `q_ready` that frame sits at (0.45, 0, 0.70) m with its z axis (the approach direction)
    along +x, its x axis up and the fingers closing along y. Among sampled IK solutions for that pose it
    is the one furthest from the joint limits (>= 0.8 rad each): straight lines of 0.25 m along +-x, y, z
    and door arcs of 90 deg either way (hinge 0.4 m to the side) follow from it without IK restarts.
    Accelerations and jerks are the Franka datasheet joint limits.
    """
    return RobotSpec(
        name="panda",
        urdf=panda_urdf(),
        arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
        finger_joints=("panda_finger_joint1", "panda_finger_joint2"),
        tool_frame="panda_grasptarget",
        q_ready=np.array([-0.4458, -0.8106, 0.4453, -2.3138, 1.7639, 3.0177, -0.6601]),
        gripper_max_width_m=0.08,
        a_max=np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
        j_max=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
        workspace_min=np.array([-0.9, -0.9, 0.02]),
        workspace_max=np.array([0.9, 0.9, 1.25]),
        q_start=np.array([0.0, -1.2523, 0.0, -2.6382, 0.0, 2.9565, 0.7854]),
    )


