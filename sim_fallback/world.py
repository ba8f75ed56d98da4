"""The PyBullet world of one scenario: the robot (the Panda unless a robot config's arm is given), the scenario's
furniture and static shapes, the parts' mechanisms, a physics clock and the ground truth.

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
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path
from typing import Literal

import numpy as np
import open3d as o3d
import pybullet as pb

from drivers.arm.robots import RobotSpec, panda
from sim_fallback.furniture import Finish, Mechanism, Part
from sim_fallback.furniture_body import grip_frame, link_indices, link_pose, load_furniture, part_links
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.layout import Layout, Placed
from sim_fallback.mechanisms import JointMechanism, MechanismForces, set_friction
from sim_fallback.resting import release_resting_contacts
from sim_fallback.scenario import Scenario
from sim_fallback.start import Q_START
from sim_fallback.static_body import static_body

PHYSICS_HZ = 240
VISUAL_TRIANGLE_FRACTION = 0.25  # robot visuals: decimated collision meshes
STIFF_FRICTION_FACTOR = 3.0  # condition "stiff": the joint's Coulomb friction times this
LOCKED_FORCE = 1e5  # condition "locked": the joint's brake (N or N m), far above anything the arm can pull
FIXED_GROUP, ALL_GROUPS = 2, 0xFFFF  # collision filter group of fixed links (furniture bodies, static shapes)
SWEEP_STEP = 0.02  # sweep_hits_robot_base: the joint's steps (m or rad)
BASE_TURNS, SHOULDER_TILTS = 12, 9  # ... and the postures of the first two robot joints tried


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
    """Ground truth of a part's joint in the robot base frame (evaluation only).

    origin: prismatic, the grip centre when closed; revolute, the point of the hinge line at the grip's
    height. direction: unit; positive joint motion opens. value: m or rad, 0 closed. body_id and links: the body and
    link indices whose pixels are the part (its link and those fixed to it, e.g. its handle); part: its name.
    """

    joint_type: Literal["prismatic", "revolute"]
    origin: np.ndarray
    direction: np.ndarray
    value: float
    upper: float
    body_id: int
    links: tuple[int, ...]
    part: str


@dataclass(frozen=True)
class LoadedPart:
    """A part of a loaded piece of furniture: its body, joint (= link) index and description."""

    body: int
    joint: int
    part: Part


class SimWorld:
    """PyBullet world of a scenario (`Scenario`: the box world; `KitchenScenario`). Context manager: leaving it
    disconnects the client.

    The target part (the scenario's `part` in its target furniture) is `cabinet_id` (its furniture's body),
    `cabinet_joint` (its joint index) and `handle_link` (its handle's link when the handle is a link of its own,
    else the part's link); `parts` are the target furniture's parts by name, `all_parts` every furniture's;
    `furniture_ids` the furniture's bodies in the layout's order, `statics_id` the body of the static shapes;
    `finishes` the looks of surfaces by (body id, link index; -1 the base) for the renderer. floor: the box world's
    4 m floor square (costs render time; off by default: background pixels then read depth 0 like out-of-range
    stereo); kitchens have their own. robot: the arm standing at the base frame's origin (a robot config's
    `robot_spec()`; default the Franka Panda), started at its `start` configuration with the scenario's jitter.
    """

    def __init__(self, scenario: Scenario | KitchenScenario, floor: bool = False,
                 robot: RobotSpec | None = None) -> None:
        self.scenario = scenario
        self.robot_spec = robot or panda()
        self.client = pb.connect(pb.DIRECT)
        self.clock = PhysicsClock(self.client)
        self.finishes: dict[tuple[int, int], Finish] = {}
        self.parts: dict[str, LoadedPart] = {}
        self.all_parts: list[LoadedPart] = []
        self._tmp = tempfile.TemporaryDirectory(prefix="axisloop_robot_")
        try:
            self._build(scenario.build_layout(floor))
        except Exception:
            self.close()
            raise

    def _build(self, layout: Layout) -> None:
        c, sc = self.client, self.scenario
        pb.setGravity(0, 0, -9.81, physicsClientId=c)
        pb.setTimeStep(self.clock.dt, physicsClientId=c)
        # contacts solved in a fixed order, not in the order of their memory addresses: an episode's outcome
        # then does not depend on what ran before it in the same process (a benchmark worker's earlier episodes)
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=c)
        robot_urdf = _low_poly_copy(self.robot_spec.urdf, Path(self._tmp.name))
        self.robot_id = pb.loadURDF(str(robot_urdf), useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE,
                                    physicsClientId=c)
        names = [pb.getJointInfo(self.robot_id, j, physicsClientId=c)[1].decode()
                 for j in range(pb.getNumJoints(self.robot_id, physicsClientId=c))]
        self.robot_joints = {name: j for j, name in enumerate(names)}
        jitter = np.asarray(sc.q_start) - Q_START  # the scenario's, around the start of whichever arm stands here
        for name, q in zip(self.robot_spec.arm_joints, self.robot_spec.start + jitter, strict=True):
            pb.resetJointState(self.robot_id, self.robot_joints[name], q, physicsClientId=c)
        fingers = self.robot_spec.finger_positions(self.robot_spec.gripper_max_width_m)
        for name, q in zip(self.robot_spec.finger_joints, fingers, strict=True):
            pb.resetJointState(self.robot_id, self.robot_joints[name], q, physicsClientId=c)
        self.furniture_ids: list[int] = []
        joints = [joint for k, placed in enumerate(layout.furniture)
                  for joint in self._load(placed, k == layout.target, layout.part)]
        self.statics_id = static_body(c, layout.statics)
        for k, shape in enumerate(layout.statics):
            if shape.finish is not None:
                self.finishes[(self.statics_id, k - 1)] = shape.finish
        fixed = [(self.robot_id, -1), *((body, -1) for body in self.furniture_ids),
                 *((self.statics_id, k - 1) for k in range(len(layout.statics)))]
        for body, link in fixed:  # what cannot move never collides with what cannot move: no contacts to solve
            pb.setCollisionFilterGroupMask(body, link, FIXED_GROUP, ALL_GROUPS ^ FIXED_GROUP, physicsClientId=c)
        release_resting_contacts(c, [*self.furniture_ids, self.statics_id])  # parts clear what they stand on
        self._mechanisms = MechanismForces(c, joints)
        self._mechanisms.apply()
        self.clock.add_hook(self._mechanisms.apply)

    def _load(self, placed: Placed, target: bool, part_name: str) -> list[JointMechanism]:
        """Load one piece of furniture, give its joints their friction and damping; the target's part in the
        scenario's condition. Its joints' mechanisms."""
        c, furniture = self.client, placed.furniture
        body = load_furniture(c, furniture, placed.T, placed.pose[3])
        self.furniture_ids.append(body)
        links = link_indices(c, body)
        for name, finish in furniture.finishes.items():
            self.finishes[(body, links[name])] = finish
        joints = []
        for part in furniture.parts:
            j = links[part.link]
            m = part.mechanism
            friction = m.friction
            if target and part.name == part_name:
                self.cabinet_id, self.cabinet_joint = body, j
                own = part_links(c, body, j)
                self.handle_link = own[1] if len(own) > 1 else j
                friction = self._condition_friction(m)
                if self.scenario.condition == "stiff":
                    m = replace(m, stiction=STIFF_FRICTION_FACTOR * m.stiction)
            self.all_parts.append(LoadedPart(body, j, part))
            if target:
                self.parts[part.name] = self.all_parts[-1]
            pb.changeDynamics(body, j, jointDamping=m.damping, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
            set_friction(c, body, j, friction)  # Coulomb friction
            if target and part.name == part_name and self.scenario.condition == "locked":
                # a velocity brake alone creeps under a sustained pull: no range either
                pb.changeDynamics(body, j, jointLowerLimit=0.0, jointUpperLimit=0.0, physicsClientId=c)
                m = replace(m, stiction=0.0)
            info = pb.getJointInfo(body, j, physicsClientId=c)
            axis = link_pose(c, body, j)[:3, :3] @ np.asarray(info[13], float)
            joints.append(JointMechanism(body, j, info[2] == pb.JOINT_PRISMATIC, axis / np.linalg.norm(axis),
                                         friction, m))
        return joints

    @property
    def time(self) -> float:
        return self.clock.time

    @property
    def target(self) -> LoadedPart:
        """The target part."""
        return self.parts[self.scenario.part]

    def _condition_friction(self, m: Mechanism) -> float:
        return {"normal": m.friction, "stiff": STIFF_FRICTION_FACTOR * m.friction,
                "locked": LOCKED_FORCE}[self.scenario.condition]

    def joint_friction(self) -> float:
        """The target joint's Coulomb friction (N or N m) in the scenario's condition: locked holds it fast."""
        return self._condition_friction(self.target.part.mechanism)

    def joint_value(self) -> float:
        """The target joint's value (m or rad; ground truth)."""
        return float(pb.getJointState(self.cabinet_id, self.cabinet_joint, physicsClientId=self.client)[0])

    def target_handle(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(grip centre, bar axis, front normal) of the target part now, base frame (ground truth)."""
        t = self.target
        return grip_frame(self.client, t.body, t.joint, t.part)

    def handle_pose(self) -> np.ndarray:
        """4x4 pose of the target's grip: origin at the grip centre, x out of its front, z as near up as that allows
        (base frame, ground truth)."""
        centre, _, normal = self.target_handle()
        y = np.cross([0.0, 0.0, 1.0], normal)
        y = y / np.linalg.norm(y) if np.linalg.norm(y) > 1e-9 else np.array([0.0, 1.0, 0.0])
        T = np.eye(4)
        T[:3, :3] = np.column_stack([normal, y, np.cross(normal, y)])
        T[:3, 3] = centre
        return T

    def truth(self, part: str | None = None) -> JointTruth:
        """The joint of the target part (or the target furniture's `part`): type, axis and value in the base frame,
        and its body and links. Evaluation and data generation only."""
        return self.part_truth(self.parts[part or self.scenario.part])

    def part_truth(self, p: LoadedPart) -> JointTruth:
        """The joint of any loaded part (`all_parts`), as `truth` gives the target's."""
        c = self.client
        info = pb.getJointInfo(p.body, p.joint, physicsClientId=c)
        T = link_pose(c, p.body, p.joint)
        direction = T[:3, :3] @ np.asarray(info[13], float)
        direction /= np.linalg.norm(direction)
        value = float(pb.getJointState(p.body, p.joint, physicsClientId=c)[0])
        grip = grip_frame(c, p.body, p.joint, p.part)[0]
        if info[2] == pb.JOINT_PRISMATIC:
            origin, joint_type = grip - direction * value, "prismatic"
        else:
            origin, joint_type = T[:3, 3] + direction * float(direction @ (grip - T[:3, 3])), "revolute"
        return JointTruth(joint_type, origin, direction, value, p.part.upper, p.body,  # type: ignore[arg-type]
                          part_links(c, p.body, p.joint), p.part.name)

    def sweep_hits_robot_base(self, value: float) -> bool:
        """Whether the moving part, opened from its present value to `value` (m or rad), must pass through the
        robot's base: its first link (the base plate), or at every sampled posture of the first two joints its
        second link (the column turning about the vertical) or its third (the shoulder, on that column). No arm
        posture gets out of the way then (a door hinged close to the robot cannot reach a wide angle). Ground
        truth for evaluation; the joints are put back as they were."""
        c, j, robot = self.client, self.cabinet_joint, self.robot_id
        first, second = (self.robot_joints[name] for name in self.robot_spec.arm_joints[:2])
        start, velocity = pb.getJointState(self.cabinet_id, j, physicsClientId=c)[:2]
        held = [pb.getJointState(robot, k, physicsClientId=c)[:2] for k in (first, second)]
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
            if any(hits(link) for link in range(-1, first)):  # the base and the links fixed to it
                return True
            for turn in postures(first, BASE_TURNS):
                pb.resetJointState(robot, first, float(turn), physicsClientId=c)
                if hits(first):
                    continue
                for tilt in postures(second, SHOULDER_TILTS):
                    pb.resetJointState(robot, second, float(tilt), physicsClientId=c)
                    if not hits(second):
                        return False
            return True
        finally:
            pb.resetJointState(self.cabinet_id, j, start, velocity, physicsClientId=c)
            for k, (q, dq) in zip((first, second), held, strict=True):
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
    """A URDF whose visuals are pybullet_data's large meshes (package://meshes/...): a copy drawn with its
    collision meshes decimated to a quarter of their triangles (any other URDF is returned as it is):
    same kinematics, dynamics and collisions, but TinyRenderer draws the frame ~30 ms faster than with
    the visual meshes (1-2 MB each) and ~6 ms faster than with whole collision meshes, whose surfaces
    the decimated ones keep within ~1 mm (median; 99% within 7 mm): arm silhouette IoU ~0.98."""
    meshes = urdf.parent / "meshes"
    if "package://meshes/" not in urdf.read_text():
        return urdf

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
