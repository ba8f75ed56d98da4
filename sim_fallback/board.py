"""Calibration scenes in PyBullet: a textured board plate (on the tool, or fixed on the table), a fixed or
wrist-mounted simulated D415, and the ground truth the calibration is compared with.

The board image comes from the caller (calibration.board renders it), so this module needs only the image,
its scale and where the board frame's origin lies on it.
"""

from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from drivers.arm.kinematics import Kinematics
from drivers.camera.base import Frame, Intrinsics
from drivers.camera.depth_noise import DepthNoise
from drivers.errors import ArmError
from sim_fallback.arm import SimArm
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.render.renderer import Render
from sim_fallback.render.tiny import TinyRenderer
from sim_fallback.scenario import Scenario, look_at
from sim_fallback.world import SimWorld

TOOL_LINK = "panda_grasptarget_hand"  # the fixed joint whose child link is the tool frame
FAR_AWAY_XY = (2.5, 2.5)  # the scenario's cabinet is moved here: calibration needs a clear workspace
BOARD_AHEAD_M = 0.03  # eye-to-hand: board centre this far beyond the tool point, facing along the tool's z
# Eye-to-hand: a camera 0.75 m from the work area, to the robot's right, looking at the board on the tool.
E2H_CAMERA_EYE, E2H_TARGET = np.array([0.42, -0.95, 0.72]), np.array([0.45, -0.25, 0.42])
# Eye-in-hand: the board flat on the table; the tool 0.45 m above it looking down.
E2I_BOARD_CENTRE, E2I_HEIGHT_M = np.array([0.5, -0.2, 0.002]), 0.45
WRIST_T_TOOL_CAMERA = (np.array([0.03, -0.05, 0.02]), np.array([0.055, 0.0, -0.09]))  # rotvec, offset (m)


@dataclass(frozen=True)
class BoardTexture:
    """A grey board image, its scale (px per m) and the board-frame (x, y) of the image's top-left edge (m)."""

    image: np.ndarray
    px_per_m: float
    origin_m: tuple[float, float]

    @property
    def corners_m(self) -> np.ndarray:
        """Board-frame (x, y) of the image's four outer corners: top-left, top-right, bottom-right, bottom-left."""
        h, w = self.image.shape[:2]
        x0, y0 = self.origin_m
        x1, y1 = x0 + w / self.px_per_m, y0 + h / self.px_per_m
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


class BoardPlate:
    """A visual-only textured plate showing the board, fixed in the base or carried by a robot link."""

    def __init__(self, world: SimWorld, texture: BoardTexture, T_base_board: np.ndarray | None = None,
                 link: int | None = None, T_link_board: np.ndarray | None = None) -> None:
        self._client, self._robot = world.client, world.robot_id
        self._tmp = tempfile.TemporaryDirectory(prefix="axisloop_board_")
        png = Path(self._tmp.name) / "board.png"
        cv2.imwrite(str(png), texture.image)
        c = texture.corners_m
        vertices = [[x, y, 0.0] for x, y in c]
        uvs = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]  # TinyRenderer: v = 0 is the image's last row
        indices = [0, 2, 1, 0, 3, 2, 0, 1, 2, 0, 2, 3]  # both windings: the printed face looks along -z
        visual = pb.createVisualShape(pb.GEOM_MESH, vertices=vertices, indices=indices, uvs=uvs,
                                      normals=[[0.0, 0.0, -1.0]] * 4, physicsClientId=self._client)
        self.body = pb.createMultiBody(0.0, -1, visual, physicsClientId=self._client)
        tex = pb.loadTexture(str(png), physicsClientId=self._client)
        pb.changeVisualShape(self.body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=self._client)
        self._link, self._T_link_board = link, T_link_board
        if link is None:
            self._place(np.asarray(T_base_board, float))
        else:
            world.clock.add_hook(self.follow)
            self.follow()

    def follow(self) -> None:
        """Move the plate with its link (called after every physics step)."""
        state = pb.getLinkState(self._robot, self._link, computeForwardKinematics=True, physicsClientId=self._client)
        self._place(_pose(state[4], state[5]) @ self._T_link_board)

    def _place(self, T: np.ndarray) -> None:
        quat = _quat(T[:3, :3])
        pb.resetBasePositionAndOrientation(self.body, T[:3, 3].tolist(), quat, physicsClientId=self._client)


class RigCamera(SimCamera):
    """The simulated D415, fixed or carried by a robot link (`link`, `T_link_camera`), drawn by TinyRenderer (the
    board's texture lives only in PyBullet), with optional Gaussian colour noise of `color_sigma` grey levels
    (images are otherwise noise-free in TinyRenderer)."""

    def __init__(self, world: SimWorld, T_base_camera: np.ndarray | None = None, link: int | None = None,
                 T_link_camera: np.ndarray | None = None, color_sigma: float = 0.0, **options) -> None:
        self._robot_body, self._client_id = world.robot_id, world.client
        self._link, self._T_link_camera = link, T_link_camera
        self.color_sigma = float(color_sigma)
        super().__init__(world, T_base_camera=T_base_camera if link is None else self._mounted_pose(), **options)

    def _mounted_pose(self) -> np.ndarray:
        state = pb.getLinkState(self._robot_body, self._link, computeForwardKinematics=True,
                                physicsClientId=self._client_id)
        return _pose(state[4], state[5]) @ self._T_link_camera

    def read(self, timeout_s: float = 2.0) -> Frame:
        frame = super().read(timeout_s)
        if self.color_sigma > 0:
            noisy = frame.color + self._rng.normal(0.0, self.color_sigma, frame.color.shape)
            frame.color = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
        return frame

    def _make_renderer(self, world: SimWorld) -> TinyRenderer:
        return TinyRenderer(world.client, self.intrinsics)

    def _capture(self) -> Render:
        if self._link is not None:
            self.T_base_camera = self._mounted_pose()
        return super()._capture()


@dataclass
class CalibrationRig:
    """A calibration scene: world, arm, camera, board plate and start joints, plus the ground truth
    (evaluation only): `true_camera` is T_base_camera (eye-to-hand) or T_tool_camera (eye-in-hand),
    `true_board` is T_tool_board (eye-to-hand) or T_base_board (eye-in-hand)."""

    setup: str
    world: SimWorld
    arm: SimArm
    camera: RigCamera
    plate: BoardPlate
    q_start: np.ndarray
    pivot_tool_m: tuple[float, float, float]
    true_camera: np.ndarray
    true_board: np.ndarray

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> CalibrationRig:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def build_rig(setup: str, texture: BoardTexture, board_centre_m: np.ndarray, resolution: tuple[int, int] = (640, 480),
              noise: DepthNoise | None = None, color_sigma: float = 0.0, seed: int = 0) -> CalibrationRig:
    """A calibration scene for `setup` ("eye-to-hand" | "eye-in-hand") with the arm at its start pose, where
    the camera sees the whole board. `board_centre_m` is the board's centre in its own frame."""
    scenario = dataclasses.replace(Scenario.make("drawer", 0), cabinet_xy=FAR_AWAY_XY)
    world = SimWorld(scenario)
    try:
        return _build(setup, world, texture, np.asarray(board_centre_m, float), resolution, noise, color_sigma, seed)
    except Exception:
        world.close()
        raise


def _build(setup: str, world: SimWorld, texture: BoardTexture, centre: np.ndarray, resolution: tuple[int, int],
           noise: DepthNoise | None, color_sigma: float, seed: int) -> CalibrationRig:
    kin = Kinematics.panda()
    link = world.robot_joints[TOOL_LINK]
    flip = np.diag([1.0, -1.0, -1.0])  # board z (into the print) against the tool's or the table's z
    intrinsics: Intrinsics = d415_intrinsics(*resolution)
    options = dict(intrinsics=intrinsics, noise=noise, seed=seed, color_sigma=color_sigma)
    if setup == "eye-to-hand":
        T_tool_board = _transform(flip, np.array([0.0, 0.0, BOARD_AHEAD_M]) - flip @ centre)
        T_base_camera = look_at(E2H_CAMERA_EYE, E2H_TARGET)
        T_start = look_at(E2H_TARGET, E2H_CAMERA_EYE)  # tool z toward the camera
        T_start[:3, 3] -= T_start[:3, :3] @ [0.0, 0.0, BOARD_AHEAD_M]
        pivot = (0.0, 0.0, BOARD_AHEAD_M)
    elif setup == "eye-in-hand":
        T_base_board = _transform(flip, E2I_BOARD_CENTRE - flip @ centre)
        R_tool_camera = cv2.Rodrigues(WRIST_T_TOOL_CAMERA[0])[0]
        T_tool_camera = _transform(R_tool_camera, WRIST_T_TOOL_CAMERA[1])
        T_start = _transform(flip, E2I_BOARD_CENTRE + [-WRIST_T_TOOL_CAMERA[1][0], 0.0, E2I_HEIGHT_M])
        pivot = (0.0, 0.0, E2I_HEIGHT_M)
    else:
        raise ValueError(f"setup must be eye-to-hand or eye-in-hand, got {setup!r}")
    q_start = _comfortable_ik(kin, T_start, world.robot_spec.q_ready)
    for name, q in zip(world.robot_spec.arm_joints, q_start, strict=True):
        pb.resetJointState(world.robot_id, world.robot_joints[name], q, physicsClientId=world.client)
    arm = SimArm(world, kin)
    if setup == "eye-to-hand":
        plate = BoardPlate(world, texture, link=link, T_link_board=T_tool_board)
        camera = RigCamera(world, T_base_camera, **options)
        return CalibrationRig(setup, world, arm, camera, plate, q_start, pivot, T_base_camera, T_tool_board)
    plate = BoardPlate(world, texture, T_base_board=T_base_board)
    camera = RigCamera(world, link=link, T_link_camera=T_tool_camera, **options)
    return CalibrationRig(setup, world, arm, camera, plate, q_start, pivot, T_tool_camera, T_base_board)


def _comfortable_ik(kin: Kinematics, T: np.ndarray, q_seed: np.ndarray, seeds: int = 24) -> np.ndarray:
    """Of the IK solutions for T from q_seed and random seeds, the one farthest from every joint limit, so that
    the stations around it stay reachable."""
    rng = np.random.default_rng(0)
    best, best_margin = None, -np.inf
    for seed in [np.asarray(q_seed, float), *rng.uniform(kin.q_min, kin.q_max, (seeds, kin.dof))]:
        try:
            q = kin.ik(T, seed, restarts=0)
        except ArmError:
            continue
        margin = float(np.min(np.minimum(q - kin.q_min, kin.q_max - q)))
        if margin > best_margin:
            best, best_margin = q, margin
    if best is None:
        raise ArmError("calibration start pose unreachable: the simulated rig's geometry is wrong")
    return best


def _transform(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _pose(position, quaternion) -> np.ndarray:
    return _transform(np.reshape(pb.getMatrixFromQuaternion(quaternion), (3, 3)), np.asarray(position, float))


def _quat(R: np.ndarray) -> list[float]:
    return Rotation.from_matrix(R).as_quat().tolist()
