"""Scoring a simulated episode against the world's ground truth: for benchmarks and reports only, never read by
the controller (the episode has finished when `score` reads the world)."""

from __future__ import annotations

import numpy as np

from deploy.config import OpeningConfig
from deploy.control.state import EpisodeResult
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.types import Axis, JointType


def calibration_error(scene, T_camera: np.ndarray) -> tuple[float, float]:
    """(translation mm, rotation deg) of a solved hand-eye camera transform against a simulated calibration
    scene's truth (`Rig.board`: T_base_camera eye-to-hand, T_tool_camera eye-in-hand)."""
    from calibration.transforms import pose_error

    return pose_error(T_camera, scene.true_camera)


def true_board_corner(scene, board) -> np.ndarray:
    """The base-frame position of `board`'s corner nearest its centre in a simulated calibration scene (the truth
    the pointing test is scored against)."""
    points = np.asarray(board.board().getChessboardCorners(), float)
    p = points[np.argmin(np.linalg.norm(points - board.center_m, axis=1))]
    return scene.true_board[:3, :3] @ p + scene.true_board[:3, 3]


USER_STREAM = 35  # the episode's random stream of its simulated user (arm signals, camera, calibration: others)


class Evaluation:
    """The truth of `world` (sim_fallback.world.SimWorld) at the start of an episode, and the scoring after it."""

    def __init__(self, world) -> None:
        self.world = world
        self.truth0 = world.truth()
        self.joint = JointType(self.truth0.joint_type)

    def user_point(self, camera, seed: int) -> tuple[int, int] | None:
        """The pixel (u, v) a user would point at on the target part's front in `camera`'s (the simulated camera
        of the rig) view now, drawn from the episode's `seed` (sim_fallback.user); None when the part is not seen."""
        from sim_fallback.user import user_pixel

        t = self.truth0
        return user_pixel(camera.link_image(), t.body_id, self.world.cabinet_joint, t.links,
                          np.random.default_rng([seed, USER_STREAM]))

    def true_axis(self) -> Axis:
        """The true joint axis at the start (base frame), for the viewer."""
        t = self.truth0
        return Axis(self.joint, np.asarray(t.origin, float), np.asarray(t.direction, float))

    def axis_error(self, axis: Axis) -> tuple[float, float | None]:
        """(angle deg, position m) of `axis` against the true joint axis; no position for a drawer (its axis is
        a direction: any parallel line is as right)."""
        t = self.truth0
        position = axis_position_error_m(t.origin, t.direction, axis.origin, axis.direction) \
            if self.joint is JointType.REVOLUTE else None
        return axis_angle_error_deg(t.direction, axis.direction), position

    def score(self, result: EpisodeResult, opening: OpeningConfig) -> dict:
        """Truth-based fields of the episode's JSON: true_opened_m (drawer) or true_opened_deg (door),
        success = true value >= target, the controller's own verdict, and the final axis's errors (position only
        for a hinge)."""
        value = self.world.truth().value
        revolute = self.joint is JointType.REVOLUTE
        angle, position = self.axis_error(result.axis) if result.axis is not None else (None, None)
        key, shown = ("true_opened_deg", float(np.degrees(value))) if revolute else ("true_opened_m", value)
        return {key: shown, "success": bool(value >= opening.target_for(self.joint)),
                "estimated_success": result.success, "axis_angle_error_deg": angle,
                "axis_position_error_m": position}
