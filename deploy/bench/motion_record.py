"""Scripted kitchen openings with per-frame truth, for `bench_motion` (deploy/bench/motion.py): GROUND TRUTH side.

Each episode is the scripted data generator's opening (sim_fallback.scripted: grasp the true handle, pull along the
true axis) filmed by the simulated D415, keeping per frame what the controller would get (depth, the arm's joints
and gripper opening) and what only evaluation may read (the (body, link) image, the joint's value, the true camera
pose). The approach is simulated (the arm moves in front of the scene); the opening is posed, not simulated: the
part is set to OPEN_FRAMES values up to the target and the arm to the grasp pose carried along the true path (IK),
so that every grasped part opens whatever the grip and the contacts would do. Episodes are cached as .npz files
(depth in the D415's millimetres) so that scoring can be repeated.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.arm.base import ArmState
from drivers.errors import ArmError

OPEN_FRAMES = 12  # frames over the opening (a 2 s pull at 5 frames per second)
HOLD_FRAMES = 2  # frames at the end, opened
SETTLE_S = 1.0  # the world runs this long before the first frame: parts that start in contact come to rest
NEAR_GRASP_M = 0.03  # a scripted grasp whose fingers met the front this near the handle is posed from there


@dataclass(frozen=True)
class MotionEpisode:
    """One scripted opening: per frame (n frames) depth_mm (n, H, W) uint16, links (n, H, W, 2) int16 (body, link),
    q (n, 7), width_m (n,), ee_pose (n, 4, 4), grasped (n,) bool, joint_value (n,), others_moved (n,): the largest
    change of any other part's joint since the first frame (m or rad: a neighbour the arm bumped, or one that swings
    by itself); and the scene's truth (`info`: task, seed, split, source, part, joint type/origin/direction, body ids,
    K, T_true)."""

    depth_mm: np.ndarray
    links: np.ndarray
    q: np.ndarray
    width_m: np.ndarray
    ee_pose: np.ndarray
    grasped: np.ndarray
    joint_value: np.ndarray
    others_moved: np.ndarray
    info: dict

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **{k: getattr(self, k) for k in _ARRAYS}, info=np.array(json.dumps(self.info)))

    @classmethod
    def load(cls, path: Path) -> MotionEpisode:
        with np.load(path) as data:
            return cls(**{k: data[k] for k in _ARRAYS}, info=json.loads(str(data["info"])))


_ARRAYS = ("depth_mm", "links", "q", "width_m", "ee_pose", "grasped", "joint_value", "others_moved")


def record_motion(task: str, seed: int, split: str, fps: float = 5.0, part: str | None = None,
                  target_furniture=None, source: str = "procedural") -> MotionEpisode:
    """The scripted opening of kitchen scenario (`task`, `seed`, `split`; `part`, `target_furniture` as in
    make_scenario) with per-frame truth. SceneError/PartError when the scene cannot be built, ArmError when the
    scripted grasp does not come within NEAR_GRASP_M of the handle, IKError when the arm cannot follow the
    opening."""
    from drivers.arm.robot_config import panda_sim_config
    from sim_fallback.arm import SimArm
    from sim_fallback.camera import SimCamera, d415_intrinsics
    from sim_fallback.scenario import make_scenario
    from sim_fallback.scripted import DEFAULT_TARGET, grasp_handle, grasp_pose, opening_path
    from sim_fallback.world import SimWorld

    class TruthCamera(SimCamera):
        """The simulated D415 that keeps the (body, link) image of its last frame (evaluation only) and can take a
        frame of the world as it is posed, without stepping it."""

        def _capture(self):
            self.last_view = super()._capture()
            return self.last_view

        def shoot(self) -> np.ndarray:
            return self._depth(self._capture())

    scenario = make_scenario("kitchen", task, seed, split, part=part, target=target_furniture)  # type: ignore[arg-type]
    target = DEFAULT_TARGET[task]
    with SimWorld(scenario) as sim:
        arm = SimArm(sim)
        sim.clock.step(int(round(SETTLE_S / sim.clock.dt)))  # the room at rest before the first frame
        camera = TruthCamera(sim, intrinsics=d415_intrinsics(), seed=seed, fps=fps)
        limits = panda_sim_config().motion_limits(arm.kin, 0.3)
        rows: list[tuple] = []
        next_t = 0.0

        others = [p for p in sim.all_parts if (p.body, p.joint) != (sim.cabinet_id, sim.cabinet_joint)]
        rest = _joint_values(sim, others)

        def keep(depth_m: np.ndarray, state: ArmState, grasped: bool) -> None:
            moved = float(np.abs(_joint_values(sim, others) - rest).max(initial=0.0))
            rows.append((np.round(depth_m * 1000).astype(np.uint16), camera.last_view.links.astype(np.int16),
                         state.q.copy(), state.gripper_width_m, arm.kin.fk(state.q), grasped, sim.joint_value(),
                         moved))

        def capture(state: ArmState, _t: float = 0.0) -> None:
            nonlocal next_t
            if state.t >= next_t - 1e-9:
                frame = camera.read()
                keep(frame.depth_m, state, False)
                next_t = (frame.index + 1) / fps

        capture(arm.state())
        try:
            grasp_handle(sim, arm, limits, target, capture)
        except ArmError:  # the fingers met the front before the handle (edge and recessed pulls): posed from here
            if np.linalg.norm(arm.kin.fk(arm.state().q)[:3, 3] - grasp_pose(sim)[:3, 3]) > NEAR_GRASP_M:
                raise
        _pose_opening(sim, arm, opening_path(arm.kin.fk(arm.state().q), sim.truth()), target,
                      lambda: keep(camera.shoot(), arm.state(), True))
        truth = sim.truth()
        info = {"task": task, "seed": seed, "split": split, "source": source, "part": truth.part,
                "joint_type": truth.joint_type, "origin": truth.origin.tolist(), "direction": truth.direction.tolist(),
                "body": truth.body_id, "part_links": list(truth.links), "robot": sim.robot_id,
                "K": camera.intrinsics.K.tolist(), "T_true": camera.T_base_camera.tolist()}
    columns = [np.stack(c) for c in zip(*rows, strict=True)]
    return MotionEpisode(*columns, info=info)


def _joint_values(sim, parts) -> np.ndarray:
    import pybullet as pb

    return np.array([pb.getJointState(p.body, p.joint, physicsClientId=sim.client)[0] for p in parts])



def _pose_opening(sim, arm, path, target: float, shoot) -> None:
    """Pose the part at OPEN_FRAMES openings up to `target` (then HOLD_FRAMES more there) with the arm's tool on the
    true path `path`, calling `shoot()` at each (truth side: the data generator). IKError when the arm cannot
    follow."""
    import pybullet as pb

    c = sim.client
    start = sim.joint_value()
    values = np.r_[np.linspace(0.0, target, OPEN_FRAMES + 1)[1:], np.full(HOLD_FRAMES, target)]
    qs = arm.kin.solve_path([path(v) for v in values], arm.state().q)
    joints = [sim.robot_joints[name] for name in sim.robot_spec.arm_joints]
    for value, q in zip(values, qs, strict=True):
        pb.resetJointState(sim.cabinet_id, sim.cabinet_joint, start + value, physicsClientId=c)
        for j, angle in zip(joints, q, strict=True):
            pb.resetJointState(sim.robot_id, j, float(angle), physicsClientId=c)
        shoot()
