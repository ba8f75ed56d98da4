"""Map where an arm grasps a handle and pulls it straight back: the grid of grip distances (ahead of the base) and
heights (above it) at which the project's grasp planner finds a pre-grasp configuration for a vertical bar facing the
robot and the whole pull, clear of the joint limits. Its region is what a robot config's `[reach]` bands should lie
in (drivers/arm/robots.py `Reach`).

    .venv/bin/python scripts/reach_scan.py openarm --pull 0.30
"""

from __future__ import annotations

import argparse

import numpy as np

from deploy.control.grasp import pregrasp_configuration
from drivers.arm.grasping import GRASP_DEPTH_M, GRASP_PITCH_RAD, grasp_pose
from drivers.arm.robot_config import load_robot_config
from drivers.errors import IKError


def reachable(kin, q_ready: np.ndarray, distance_m: float, height_m: float, pull_m: float, steps: int = 6) -> bool:
    """Whether a bar `distance_m` ahead at `height_m`, its front facing the robot, is grasped and pulled `pull_m`."""
    normal = np.array([-1.0, 0.0, 0.0])
    T = grasp_pose(np.array([distance_m, 0.0, height_m]), normal, np.array([0.0, 0.0, 1.0]), GRASP_DEPTH_M,
                   GRASP_PITCH_RAD)
    path = []
    for k in range(1, steps + 1):
        P = T.copy()
        P[:3, 3] += normal * pull_m * k / steps
        path.append(P)
    try:
        pregrasp_configuration(kin, q_ready, T, [path], 0.1)
    except IKError:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robot", help="a shipped robot config's name or a TOML file")
    parser.add_argument("--pull", type=float, default=0.30, help="straight pull (m)")
    args = parser.parse_args()
    config = load_robot_config(args.robot)
    kin, q_ready = config.kinematics(), np.array(config.q_ready)
    distances, heights = np.arange(0.35, 0.91, 0.05), np.arange(0.3, 1.01, 0.05)
    print("height \\ distance (m) " + " ".join(f"{d:.2f}" for d in distances))
    for h in heights:
        row = "    ".join("#" if reachable(kin, q_ready, d, h, args.pull) else "." for d in distances)
        print(f"{h:.2f}                  {row}")


if __name__ == "__main__":
    main()
