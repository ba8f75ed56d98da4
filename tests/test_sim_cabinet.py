"""Procedural cabinets and scenarios: URDF loads, limits, physics of the joint, reachability, determinism."""

import dataclasses
import re

import numpy as np
import pybullet as pb
import pytest

from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import load_robot_config
from sim_fallback.cabinet_urdf import cabinet_urdf, random_cabinet
from sim_fallback.scenario import Scenario
from sim_fallback.scripted import DEFAULT_TARGET, grasp_pose, opening_path
from sim_fallback.world import SimWorld

KINDS_SPLITS = [("drawer", "train"), ("drawer", "test"), ("door", "train"), ("door", "test")]


@pytest.mark.parametrize(("kind", "split"), KINDS_SPLITS)
def test_urdf_loads_with_the_specified_joint(kind, split, tmp_path):
    spec = random_cabinet(kind, 3, split)
    path = tmp_path / "cabinet.urdf"
    path.write_text(cabinet_urdf(spec))
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
        joint = pb.getJointInfo(body, 0, physicsClientId=client)
        handle = pb.getJointInfo(body, 1, physicsClientId=client)
        assert joint[1].decode() == f"{kind}_joint"
        assert joint[2] == (pb.JOINT_PRISMATIC if kind == "drawer" else pb.JOINT_REVOLUTE)
        assert joint[8] == 0.0 and joint[9] == pytest.approx(spec.joint_upper, abs=1e-6)
        np.testing.assert_allclose(joint[13], spec.joint_axis_cabinet, atol=1e-9)
        assert handle[12].decode() == "handle" and handle[2] == pb.JOINT_FIXED
        state = pb.getLinkState(body, 1, computeForwardKinematics=True, physicsClientId=client)
        np.testing.assert_allclose(state[4], spec.handle_cabinet, atol=1e-6)  # URDF matches the spec
    finally:
        pb.disconnect(client)


@pytest.mark.parametrize(("kind", "split"), KINDS_SPLITS)
def test_joint_limits_leave_room_beyond_the_hardest_goal(kind, split):
    uppers = [random_cabinet(kind, seed, split).joint_upper for seed in range(100)]
    hardest = 0.45 + 0.05 if kind == "drawer" else np.radians(70 + 10)
    assert min(uppers) >= hardest
    assert max(uppers) - min(uppers) > 0.01  # randomised


def test_random_cabinets_are_deterministic_and_families_disjoint():
    spec = random_cabinet("door", 5, "train")
    assert spec == random_cabinet("door", 5, "train")
    assert cabinet_urdf(spec) == cabinet_urdf(random_cabinet("door", 5, "train"))
    assert random_cabinet("door", 5, "train") != random_cabinet("door", 6, "train")
    for kind in ("drawer", "door"):
        train = [random_cabinet(kind, s, "train") for s in range(200)]
        test = [random_cabinet(kind, s, "test") for s in range(200)]
        assert max(c.width_m for c in train) < min(c.width_m for c in test)
        assert max(c.height_m for c in train) < min(c.height_m for c in test)
        assert {c.handle_style for c in train} == {"bar"}
        assert {c.handle_style for c in test} == {"bar", "knob"}
        sizes = {dataclasses.astuple(c)[3:] for c in train}
        assert not sizes & {dataclasses.astuple(c)[3:] for c in test}
        assert len({c.width_m for c in train}) == len(train)  # every seed differs


def test_scenario_is_deterministic_and_like_rgbmanip():
    assert Scenario.make("drawer", 4) == Scenario.make("drawer", 4)
    assert Scenario.make("drawer", 4) != Scenario.make("drawer", 5)
    for seed in range(30):
        sc = Scenario.make("door", seed, "test")
        T = sc.T_base_cabinet
        front = T[:3, :3] @ [sc.cabinet.depth_m / 2, 0, 0] + T[:3, 3]
        assert 0.5 <= np.hypot(*front[:2]) <= 0.85  # RGBManip's object distance
        facing = T[:2, 0]  # the front normal points back at the robot, within +-0.2 rad
        assert np.arccos(np.clip(facing @ -front[:2] / np.linalg.norm(front[:2]), -1, 1)) <= 0.2 + 1e-9
        handle_z = (T[:3, :3] @ sc.cabinet.handle_cabinet + T[:3, 3])[2]
        assert 0.62 <= handle_z <= 0.78
        camera = sc.T_base_camera
        target = T[:3, :3] @ [sc.cabinet.depth_m / 2, 0, sc.cabinet.height_m / 2] + T[:3, 3]
        assert 0.65 <= np.linalg.norm(camera[:3, 3] - target) <= 1.0
        assert camera[2, 2] < 0  # looking down


def test_joint_friction_holds_below_it_and_yields_above():
    with SimWorld(Scenario.make("drawer", 2)) as world:
        truth = world.truth()
        friction = world.scenario.cabinet.friction
        c, body = world.client, world.cabinet_id

        def push(force_n: float, steps: int = 120) -> float:
            start = world.joint_value()
            for _ in range(steps):
                centre = pb.getLinkState(body, 0, physicsClientId=c)[0]
                pb.applyExternalForce(body, 0, (force_n * truth.direction).tolist(), centre, pb.WORLD_FRAME,
                                      physicsClientId=c)
                world.clock.step()
            return world.joint_value() - start

        assert abs(push(0.5 * friction)) < 1e-4
        assert push(3.0 * friction) > 0.01
        for _ in range(480):  # pushed well past the limit: the limit holds
            push(100.0, 1)
        assert world.joint_value() <= truth.upper + 0.01


@pytest.mark.parametrize("kind", ["drawer", "door"])
def test_truth_axis_moves_the_handle_as_the_joint_opens(kind):
    with SimWorld(Scenario.make(kind, 1)) as world:
        truth = world.truth()
        assert truth.joint_type == ("prismatic" if kind == "drawer" else "revolute")
        assert np.linalg.norm(truth.direction) == pytest.approx(1.0)
        closed = world.handle_pose()
        pb.resetJointState(world.cabinet_id, 0, 0.3, physicsClientId=world.client)
        opened = world.handle_pose()
        expected = opening_path(closed, truth)(0.3)
        np.testing.assert_allclose(opened, expected, atol=1e-6)
        # opening brings the handle toward the robot side of the front
        assert (opened[:3, 3] - closed[:3, 3]) @ closed[:3, 0] > 0.01
        assert world.truth().value == pytest.approx(0.3)
        if kind == "door":  # the handle sits near the free edge, the door's width from the hinge
            offset = closed[:3, 3] - truth.origin
            radius = np.linalg.norm(offset - (offset @ truth.direction) * truth.direction)
            assert world.scenario.cabinet.width_m - 0.08 < radius < world.scenario.cabinet.width_m + 0.02


@pytest.mark.parametrize(("kind", "split"), KINDS_SPLITS)
def test_handles_are_reachable_by_ik(kind, split):
    kin = Kinematics.panda()
    rng = np.random.default_rng(0)
    for seed in range(4):
        sc = Scenario.make(kind, seed, split)
        with SimWorld(sc) as world:
            T_grasp = grasp_pose(world)
            path = opening_path(T_grasp, world.truth())
        for s in (0.0, DEFAULT_TARGET[kind]):
            q = kin.ik(path(s), np.array(sc.q_start), rng=rng)
            np.testing.assert_allclose(kin.fk(q), path(s), atol=1e-3)


def test_worlds_coexist_and_close():
    a, b = SimWorld(Scenario.make("drawer", 0)), SimWorld(Scenario.make("door", 0))
    assert a.client != b.client
    pb.resetJointState(a.cabinet_id, 0, 0.1, physicsClientId=a.client)
    assert b.joint_value() == 0.0 and a.joint_value() == pytest.approx(0.1)
    a.close()
    a.close()  # idempotent
    assert not pb.isConnected(a.client) and pb.isConnected(b.client)
    b.close()


def _render_depth(urdf: str, tmp_path, opening: float, eye: list[float]) -> np.ndarray:
    path = tmp_path / "cabinet.urdf"
    path.write_text(urdf)
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
        pb.resetJointState(body, 0, opening, physicsClientId=client)
        view = pb.computeViewMatrix(eye, [0.0, 0.0, 0.25], [0.0, 0.0, 1.0])
        proj = pb.computeProjectionMatrixFOV(60.0, 4 / 3, 0.1, 5.0)
        _, _, _, depth, _ = pb.getCameraImage(320, 240, view, proj, renderer=pb.ER_TINY_RENDERER,
                                              physicsClientId=client)
        return np.asarray(depth, np.float32)
    finally:
        pb.disconnect(client)


@pytest.mark.parametrize("split", ["train", "test"])
def test_drawer_body_looks_like_its_panels(split, tmp_path):
    spec = random_cabinet("drawer", 0, split)
    urdf = cabinet_urdf(spec)
    body = re.search(r'<link name="body">.*?</link>', urdf, re.S).group(0)
    collisions = re.findall(r"<collision>(.*?)</collision>", body)
    assert body.count("<visual>") < len(collisions)  # drawn with fewer, larger boxes than it is built of
    panels = "".join(f'<visual>{c}<material name="body_colour"/></visual>' for c in collisions)
    drawn_as_built = re.sub(r"<visual>.*?</visual>", "", body).replace("<collision>", panels + "<collision>", 1)
    as_built = urdf.replace(body, drawn_as_built)
    for opening in (0.0, 0.3):
        for eye in ([1.3, 0.6, 1.0], [-1.0, -0.8, 1.1], [1.2, -0.3, 0.1]):
            drawn = _render_depth(urdf, tmp_path, opening, eye)
            built = _render_depth(as_built, tmp_path, opening, eye)
            assert (drawn < 1.0).mean() > 0.05  # the cabinet is in view
            assert np.mean(np.abs(drawn - built) > 1e-5) < 0.002


def test_a_door_hinged_close_to_the_robot_cannot_sweep_past_its_base(near_doors):
    """Evaluation only: placed near (0.4-0.7 m), test door 32 is hinged so close to the robot that 70 deg would
    pass through the base, door 17 through the shoulder at every posture of the first two joints; 45 deg clears
    both, and so does every drawer pull of the benchmarks. The joints are put back as they were."""
    near = load_robot_config(near_doors).robot_spec().reach
    with SimWorld(Scenario.make("door", 32, "test", reach=near)) as world:
        assert world.sweep_hits_robot_base(np.radians(70.0))
        assert not world.sweep_hits_robot_base(np.radians(45.0))
        assert world.joint_value() == 0.0
        for k in (0, 1):
            assert pb.getJointState(world.robot_id, k, physicsClientId=world.client)[0] == pytest.approx(
                world.scenario.q_start[k])
    with SimWorld(Scenario.make("door", 17, "test", reach=near)) as world:  # clears plate and column, not shoulder
        assert world.sweep_hits_robot_base(np.radians(70.0))
        assert not world.sweep_hits_robot_base(np.radians(45.0))
    with SimWorld(Scenario.make("drawer", 0, "test", reach=near)) as world:
        assert not world.sweep_hits_robot_base(0.45)
