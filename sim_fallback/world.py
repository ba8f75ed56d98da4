"""The PyBullet world of one scenario: Panda, cabinet on a pedestal, physics clock and ground truth.

Each `SimWorld` owns its own DIRECT-mode client, so several can coexist. Devices (`SimCamera`,
`SimArm`) are built from a world but keep only a `PhysicsClock` and body ids, never the world: the
ground truth (`SimWorld.truth()`) is for evaluation code and scripted data generation only.
"""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Literal

import numpy as np
import open3d as o3d
import pybullet as pb

from drivers.arm.robots import panda
from sim_fallback.cabinet_urdf import write_cabinet_urdf
from sim_fallback.scenario import Scenario

PHYSICS_HZ = 240
VISUAL_TRIANGLE_FRACTION = 0.25  # robot visuals: decimated collision meshes
STIFF_FRICTION_FACTOR = 3.0  # condition "stiff": the joint's Coulomb friction times this
LOCKED_FORCE = 1e5  # condition "locked": the joint's brake (N or N m), far above anything the arm can pull
SWEEP_STEP = 0.02  # sweep_hits_robot_base: the joint's steps (m or rad)
BASE_TURNS, SHOULDER_TILTS = 12, 9  # ... and the postures of the first two robot joints tried
FLOOR_SIZE_M = 4.0  # a floor box, cheaper to render than pybullet_data's plane (docs/benchmarks.md)


class PhysicsClock:
    """Steps one PyBullet client and keeps simulated time; hooks run after every physics step."""

    def __init__(self, client: int, hz: int = PHYSICS_HZ) -> None:
        self.client = client
        self.dt = 1.0 / hz
        self.steps = 0
        self._hooks: list[Callable[[], None]] = []

    @property
    def time(self) -> float:
        """Simulated seconds since the world was built."""
        return self.steps * self.dt

    def add_hook(self, hook: Callable[[], None]) -> None:
        self._hooks.append(hook)

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            pb.stepSimulation(physicsClientId=self.client)
            self.steps += 1
            for hook in self._hooks:
                hook()


@dataclass(frozen=True)
class JointTruth:
    """Ground truth of the cabinet joint in the robot base frame (evaluation only).

    origin: prismatic, the grip centre when closed; revolute, the point of the hinge line at the grip's
    height. direction: unit; positive joint motion opens. value: m or rad, 0 closed.
    """

    joint_type: Literal["prismatic", "revolute"]
    origin: np.ndarray
    direction: np.ndarray
    value: float
    upper: float


class SimWorld:
    """PyBullet world of a scenario. Context manager: leaving it disconnects the client.

    floor: draw a 4 m floor square under the robot and cabinet (costs render time; off by default,
    background pixels then read depth 0 like out-of-range stereo).
    """

    def __init__(self, scenario: Scenario, floor: bool = False) -> None:
        self.scenario = scenario
        self.client = pb.connect(pb.DIRECT)
        self.clock = PhysicsClock(self.client)
        self._tmp = tempfile.TemporaryDirectory(prefix="axisloop_cabinet_")
        try:
            self._build(floor)
        except Exception:
            self.close()
            raise

    def _build(self, floor: bool) -> None:
        c, sc = self.client, self.scenario
        pb.setGravity(0, 0, -9.81, physicsClientId=c)
        pb.setTimeStep(self.clock.dt, physicsClientId=c)
        # contacts solved in a fixed order, not in the order of their memory addresses: an episode's outcome
        # then does not depend on what ran before it in the same process (a benchmark worker's earlier episodes)
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=c)
        self.robot_spec = panda()
        robot_urdf = _low_poly_copy(self.robot_spec.urdf, Path(self._tmp.name))
        self.robot_id = pb.loadURDF(str(robot_urdf), useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE,
                                    physicsClientId=c)
        names = [pb.getJointInfo(self.robot_id, j, physicsClientId=c)[1].decode()
                 for j in range(pb.getNumJoints(self.robot_id, physicsClientId=c))]
        self.robot_joints = {name: j for j, name in enumerate(names)}
        for name, q in zip(self.robot_spec.arm_joints, sc.q_start, strict=True):
            pb.resetJointState(self.robot_id, self.robot_joints[name], q, physicsClientId=c)
        half_open = self.robot_spec.gripper_max_width_m / 2
        for name in self.robot_spec.finger_joints:
            pb.resetJointState(self.robot_id, self.robot_joints[name], half_open, physicsClientId=c)

        spec, T = sc.cabinet, sc.T_base_cabinet
        urdf = write_cabinet_urdf(spec, Path(self._tmp.name))
        quat = pb.getQuaternionFromEuler([0.0, 0.0, sc.cabinet_yaw])
        self.cabinet_id = pb.loadURDF(str(urdf), T[:3, 3].tolist(), quat, useFixedBase=True,
                                      physicsClientId=c)
        self.cabinet_joint, self.handle_link = 0, 1
        pb.changeDynamics(self.cabinet_id, self.cabinet_joint, jointDamping=spec.damping, linearDamping=0.0,
                          angularDamping=0.0, physicsClientId=c)
        pb.setJointMotorControl2(self.cabinet_id, self.cabinet_joint, pb.VELOCITY_CONTROL, targetVelocity=0.0,
                                 force=self.joint_friction(), physicsClientId=c)  # Coulomb friction
        if sc.condition == "locked":  # a velocity brake alone creeps under a sustained pull: no range either
            pb.changeDynamics(self.cabinet_id, self.cabinet_joint, jointLowerLimit=0.0, jointUpperLimit=0.0,
                              physicsClientId=c)

        half = [spec.depth_m / 2 - 0.01, spec.width_m / 2 - 0.01, sc.pedestal_height_m / 2]
        centre = T[:3, :3] @ [0.0, 0.0, -sc.pedestal_height_m / 2] + T[:3, 3]
        _static_box(c, half, centre.tolist(), quat, (0.45, 0.45, 0.47, 1.0))
        if floor:
            _static_box(c, [FLOOR_SIZE_M / 2, FLOOR_SIZE_M / 2, 0.005], [0.5, 0.0, -0.005], [0, 0, 0, 1],
                        (0.62, 0.6, 0.55, 1.0))

    @property
    def time(self) -> float:
        return self.clock.time

    def joint_friction(self) -> float:
        """The cabinet joint's Coulomb friction (N or N m) in the scenario's condition: locked holds it fast."""
        friction = self.scenario.cabinet.friction
        return {"normal": friction, "stiff": STIFF_FRICTION_FACTOR * friction,
                "locked": LOCKED_FORCE}[self.scenario.condition]

    def joint_value(self) -> float:
        """The cabinet joint's value (m or rad; ground truth)."""
        return float(pb.getJointState(self.cabinet_id, self.cabinet_joint, physicsClientId=self.client)[0])

    def handle_pose(self) -> np.ndarray:
        """4x4 pose of the handle frame (grip centre, cabinet axes) in the base frame (ground truth)."""
        state = pb.getLinkState(self.cabinet_id, self.handle_link, computeForwardKinematics=True,
                                physicsClientId=self.client)
        return _pose(state[4], state[5])

    def truth(self) -> JointTruth:
        """The cabinet joint's type, axis and value in the base frame. Evaluation and data generation only."""
        spec, T = self.scenario.cabinet, self.scenario.T_base_cabinet
        direction = T[:3, :3] @ spec.joint_axis_cabinet
        value = self.joint_value()
        if spec.kind == "drawer":
            origin = T[:3, :3] @ spec.handle_cabinet + T[:3, 3]
            joint_type = "prismatic"
        else:
            hinge = T[:3, :3] @ spec.joint_origin_cabinet + T[:3, 3]
            origin = hinge + direction * float(direction @ (self.handle_pose()[:3, 3] - hinge))
            joint_type = "revolute"
        return JointTruth(joint_type, origin, direction, value, spec.joint_upper)

    def sweep_hits_robot_base(self, value: float) -> bool:
        """Whether the moving part, opened from its present value to `value` (m or rad), must pass through the
        robot's base: its first link (the base plate), or at every sampled posture of the first two joints its
        second link (the column turning about the vertical) or its third (the shoulder, on that column). No arm
        posture gets out of the way then (a door hinged close to the robot cannot reach a wide angle). Ground
        truth for evaluation; the joints are put back as they were."""
        c, j, robot = self.client, self.cabinet_joint, self.robot_id
        start, velocity = pb.getJointState(self.cabinet_id, j, physicsClientId=c)[:2]
        held = [pb.getJointState(robot, k, physicsClientId=c)[:2] for k in (0, 1)]
        values = np.append(np.arange(start, value, SWEEP_STEP if value >= start else -SWEEP_STEP), value)

        def hits(link: int) -> bool:
            for q in values:
                pb.resetJointState(self.cabinet_id, j, float(q), physicsClientId=c)
                if pb.getClosestPoints(self.cabinet_id, robot, 0.0, j, link, physicsClientId=c):
                    return True
            return False

        def postures(joint: int, count: int) -> np.ndarray:
            return np.linspace(*pb.getJointInfo(robot, joint, physicsClientId=c)[8:10], count)

        try:
            if hits(-1):
                return True
            for turn in postures(0, BASE_TURNS):
                pb.resetJointState(robot, 0, float(turn), physicsClientId=c)
                if hits(0):
                    continue
                for tilt in postures(1, SHOULDER_TILTS):
                    pb.resetJointState(robot, 1, float(tilt), physicsClientId=c)
                    if not hits(1):
                        return False
            return True
        finally:
            pb.resetJointState(self.cabinet_id, j, start, velocity, physicsClientId=c)
            for k, (q, dq) in enumerate(held):
                pb.resetJointState(robot, k, q, dq, physicsClientId=c)

    def close(self) -> None:
        """Disconnect the client and remove the generated URDF (idempotent)."""
        if pb.isConnected(self.client):
            pb.disconnect(self.client)
        self._tmp.cleanup()

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _low_poly_copy(urdf: Path, directory: Path) -> Path:
    """A copy of the robot URDF drawn with its collision meshes decimated to a quarter of their triangles:
    same kinematics, dynamics and collisions, but TinyRenderer draws the frame ~30 ms faster than with
    the visual meshes (1-2 MB each) and ~6 ms faster than with whole collision meshes, whose surfaces
    the decimated ones keep within ~1 mm (median; 99% within 7 mm): arm silhouette IoU ~0.98."""
    meshes = urdf.parent / "meshes"

    def low_poly(match: re.Match) -> str:
        return str(_decimated(meshes / "collision" / f"{match.group(1)}.obj"))

    def visual(block: re.Match) -> str:
        return re.sub(r"package://meshes/(?:visual|collision)/(\w+)\.obj", low_poly, block.group(0))

    text = re.sub(r"<visual>.*?</visual>", visual, urdf.read_text(), flags=re.S)
    copy = directory / urdf.name
    copy.write_text(text.replace("package://meshes/", f"{meshes}/"))
    return copy


@cache
def _decimated(mesh_path: Path) -> Path:
    """`mesh_path` simplified (quadric error) to VISUAL_TRIANGLE_FRACTION of its triangles (kept whole
    under 100, like the fingers), made once per machine: kept in the user's cache directory, named by
    the source file, its size and time, the fraction and the Open3D version."""
    stat = mesh_path.stat()
    key = f"{mesh_path.resolve()}:{stat.st_size}:{stat.st_mtime_ns}:{VISUAL_TRIANGLE_FRACTION}:{o3d.__version__}"
    out = _cache_directory() / f"{mesh_path.stem}_{hashlib.sha1(key.encode()).hexdigest()[:12]}.obj"
    if out.exists():
        return out
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh = o3d.io.read_triangle_mesh(str(mesh_path))
        mesh.remove_duplicated_vertices()
        n = len(mesh.triangles)
        low = mesh if n < 100 else mesh.simplify_quadric_decimation(round(n * VISUAL_TRIANGLE_FRACTION))
        low.compute_vertex_normals()
        partial = out.with_name(f"{out.stem}.{os.getpid()}.obj")  # then renamed: parallel workers never see half a file
        o3d.io.write_triangle_mesh(str(partial), low, write_triangle_uvs=False)
    os.replace(partial, out)
    return out


def _cache_directory() -> Path:
    """$XDG_CACHE_HOME/axisloop/meshes (default ~/.cache/axisloop/meshes), created when missing."""
    directory = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "axisloop" / "meshes"
    directory.mkdir(parents=True, exist_ok=True)
    return directory


def _static_box(client: int, half: list[float], pos: list[float], quat, rgba: tuple) -> int:
    shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=client)
    visual = pb.createVisualShape(pb.GEOM_BOX, halfExtents=half, rgbaColor=rgba, physicsClientId=client)
    return pb.createMultiBody(0.0, shape, visual, pos, quat, physicsClientId=client)


def _pose(position, quaternion) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.reshape(pb.getMatrixFromQuaternion(quaternion), (3, 3))
    T[:3, 3] = position
    return T
