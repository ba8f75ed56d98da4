"""Map where an arm grasps a handle and pulls it straight back: the grid of grip distances (ahead of the base) and
heights (above it) at which the project's grasp planner finds a pre-grasp configuration for a vertical bar facing the
robot and the whole pull, clear of the joint limits. Its region is what a robot config's `[reach]` bands should lie
in (drivers/arm/robots.py `Reach`).

    .venv/bin/python scripts/reach_scan.py openarm --pull 0.30
    .venv/bin/python scripts/reach_scan.py panda_sim --pull 0.45 --pitch 1.1 --heights 0.2 0.75   # from above
"""

from __future__ import annotations

import argparse

import numpy as np

from deploy.control.grasp import pregrasp_configuration
from drivers.arm.grasping import GRASP_DEPTH_M, GRASP_PITCH_RAD, grasp_pose
from drivers.arm.motion import arc_path
from drivers.arm.robot_config import load_robot_config
from drivers.errors import IKError


def reachable(kin, q_ready: np.ndarray, distance_m: float, height_m: float, pull_m: float, steps: int = 6,
              pitch_rad: float = GRASP_PITCH_RAD, bar: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> bool:
    """Whether a bar along `bar` `distance_m` ahead at `height_m`, its front facing the robot, is grasped (tilted
    down by `pitch_rad`) and pulled `pull_m`."""
    normal = np.array([-1.0, 0.0, 0.0])
    T = grasp_pose(np.array([distance_m, 0.0, height_m]), normal, np.array(bar), GRASP_DEPTH_M, pitch_rad)
    path = []
    for k in range(1, steps + 1):
        P = T.copy()
        P[:3, 3] += normal * pull_m * k / steps
        path.append(P)
    return _carried(kin, q_ready, T, path)


def swings(kin, q_ready: np.ndarray, distance_m: float, height_m: float, angle_rad: float, hinge_m: float = 0.4,
           steps: int = 9, pitch_rad: float = GRASP_PITCH_RAD) -> bool:
    """Whether a vertical bar `distance_m` ahead at `height_m` on a door facing the robot, hinged `hinge_m` to either
    side, is grasped (tilted down by `pitch_rad`) and swung open by `angle_rad` (the tool turning with the door)."""
    normal = np.array([-1.0, 0.0, 0.0])
    T = grasp_pose(np.array([distance_m, 0.0, height_m]), normal, np.array([0.0, 0.0, 1.0]), GRASP_DEPTH_M,
                   pitch_rad)
    for side in (-1.0, 1.0):
        hinge = np.array([distance_m, side * hinge_m, height_m])
        arc = arc_path(T, hinge, np.array([0.0, 0.0, -side]))  # the grip comes out toward the robot
        if not _carried(kin, q_ready, T, [arc(angle_rad * k / steps) for k in range(1, steps + 1)]):
            return False
    return True


def _carried(kin, q_ready: np.ndarray, T: np.ndarray, path: list[np.ndarray]) -> bool:
    try:
        pregrasp_configuration(kin, q_ready, T, [path], 0.1)
    except IKError:
        return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("robot", help="a shipped robot config's name or a TOML file")
    parser.add_argument("--pull", type=float, default=0.30, help="straight pull (m)")
    parser.add_argument("--pitch", type=float, default=GRASP_PITCH_RAD,
                        help="approach tilted down this far (rad): the usual grasp, or one from above")
    parser.add_argument("--door", type=float, default=None,
                        help="a door swung this far (deg, hinged 0.4 m to either side) instead of a pull")
    parser.add_argument("--horizontal", action="store_true", help="a horizontal bar (a drawer's), not a vertical one")
    parser.add_argument("--heights", type=float, nargs=2, default=(0.3, 1.0),
                        help="heights scanned (m, lowest, highest)")
    args = parser.parse_args()
    config = load_robot_config(args.robot)
    kin, q_ready = config.kinematics(), np.array(config.q_ready)
    bar = (0.0, 1.0, 0.0) if args.horizontal else (0.0, 0.0, 1.0)
    distances, heights = np.arange(0.35, 0.91, 0.05), np.arange(args.heights[0], args.heights[1] + 0.01, 0.05)
    print("height \\ distance (m) " + " ".join(f"{d:.2f}" for d in distances))
    for h in heights:
        row = "    ".join("#" if (reachable(kin, q_ready, d, h, args.pull, pitch_rad=args.pitch, bar=bar)
                                   if args.door is None else
                                   swings(kin, q_ready, d, h, np.radians(args.door), pitch_rad=args.pitch)) else "."
                           for d in distances)
        print(f"{h:.2f}                  {row}")


if __name__ == "__main__":
    main()
