"""Kinematics: FK against PyBullet, Jacobian against finite differences, IK round trips and failures,
the rest-posture pull in the null space and per-tick tracking near singularities."""

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from drivers.arm.kinematics import Kinematics
from drivers.arm.robots import panda
from drivers.errors import ArmError

# A configuration 0.4 rad from the ready pose where the tool Jacobian loses rank (smallest singular value
# ~5e-5), found by minimising that singular value from the ready pose.
Q_SINGULAR = np.array([-0.446, -0.787, 0.443, -2.363, np.pi / 2, 3.346, -0.66])


@pytest.fixture(scope="module")
def kin() -> Kinematics:
    return Kinematics.panda()


def _pose(position, rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation, position
    return T


def test_model_is_the_panda_arm(kin):
    robot = panda()
    assert kin.dof == 7
    assert kin.joint_names == list(robot.arm_joints)
    assert np.all(kin.q_min < kin.q_max)
    assert kin.q_max[3] == 0.0 and kin.q_min[5] == pytest.approx(-0.0873)
    assert np.allclose(kin.v_max, [2.175] * 4 + [2.61] * 3)


def test_fk_matches_pybullet(kin):
    robot = panda()
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(robot.urdf), useFixedBase=True, physicsClientId=client)
        links = {pb.getJointInfo(body, i, physicsClientId=client)[12].decode(): i
                 for i in range(pb.getNumJoints(body, physicsClientId=client))}
        joints = {pb.getJointInfo(body, i, physicsClientId=client)[1].decode(): i
                  for i in range(pb.getNumJoints(body, physicsClientId=client))}
        rng = np.random.default_rng(0)
        for q in rng.uniform(kin.q_min, kin.q_max, (30, kin.dof)):
            for name, value in zip(kin.joint_names, q, strict=True):
                pb.resetJointState(body, joints[name], value, physicsClientId=client)
            state = pb.getLinkState(body, links[robot.tool_frame], computeForwardKinematics=True,
                                    physicsClientId=client)
            position, quaternion = np.array(state[4]), np.array(state[5])
            rotation = np.array(pb.getMatrixFromQuaternion(quaternion)).reshape(3, 3)
            T = kin.fk(q)
            assert np.allclose(T[:3, 3], position, atol=1e-6)
            assert np.allclose(T[:3, :3], rotation, atol=1e-6)
    finally:
        pb.disconnect(client)


def test_jacobian_matches_finite_differences(kin):
    rng = np.random.default_rng(1)
    h = 1e-6
    for q in rng.uniform(kin.q_min, kin.q_max, (5, kin.dof)):
        J = kin.jacobian(q)
        T = kin.fk(q)
        for j in range(kin.dof):
            dq = np.zeros(kin.dof)
            dq[j] = h
            T_h = kin.fk(q + dq)
            linear = (T_h[:3, 3] - T[:3, 3]) / h
            angular = pin.log3(T_h[:3, :3] @ T[:3, :3].T) / h  # base-aligned axes
            assert np.allclose(J[:3, j], linear, atol=1e-5)
            assert np.allclose(J[3:, j], angular, atol=1e-5)


def test_ready_pose_points_forward_at_handle_height(kin):
    q = panda().q_ready
    assert np.all(q > kin.q_min + 0.8) and np.all(q < kin.q_max - 0.8)
    T = kin.fk(q)
    assert np.allclose(T[:3, 2], [1, 0, 0], atol=1e-3)  # approach axis forward, horizontal
    assert abs(T[2, 1]) < 1e-3  # fingers close horizontally
    assert np.allclose(T[:3, 3], [0.45, 0.0, 0.70], atol=1e-3)


@pytest.mark.parametrize("direction", np.vstack([np.eye(3), -np.eye(3)]).tolist())
def test_lines_from_the_ready_pose_need_no_restart(kin, direction):
    T0 = kin.fk(panda().q_ready)
    poses = [_pose(T0[:3, 3] + d * np.array(direction), T0[:3, :3]) for d in np.linspace(0, 0.25, 26)]
    qs = kin.solve_path(poses, panda().q_ready, restarts=0)
    assert qs.shape == (26, 7)
    np.testing.assert_allclose(qs[0], panda().q_ready, atol=1e-3)  # the start needs no motion
    for q, T in zip(qs, poses, strict=True):  # every waypoint reached, within the IK's tolerances
        assert np.linalg.norm(kin.fk(q)[:3, 3] - T[:3, 3]) <= 1e-4
        assert np.linalg.norm(pin.log3(kin.fk(q)[:3, :3].T @ T[:3, :3])) <= 1e-3
    assert np.all(qs >= kin.q_min) and np.all(qs <= kin.q_max)
    assert np.abs(np.diff(qs, axis=0)).max() < 0.25  # 1 cm apart: at most 0.2 rad (stretched out ahead), no jump


@pytest.mark.parametrize(("hinge_y", "sign"), [(0.4, -1.0), (-0.4, 1.0)])
def test_door_arcs_from_the_ready_pose_need_no_restart(kin, hinge_y, sign):
    T0 = kin.fk(panda().q_ready)
    hinge = T0[:3, 3] + [0.0, hinge_y, 0.0]
    poses = []
    for angle in np.radians(np.linspace(0, 90, 31)):
        R = pin.exp3(np.array([0.0, 0.0, sign * angle]))
        poses.append(_pose(hinge + R @ (T0[:3, 3] - hinge), R @ T0[:3, :3]))
    qs = kin.solve_path(poses, panda().q_ready, restarts=0)
    assert np.linalg.norm(kin.fk(qs[-1])[:3, 3] - T0[:3, 3]) > 0.5  # swung a quarter circle (r = 0.4 m)


def test_ik_round_trip_on_random_reachable_poses(kin):
    rng = np.random.default_rng(2)
    seed = panda().q_ready
    targets = rng.uniform(kin.q_min, kin.q_max, (500, kin.dof))
    solved = 0
    for q_true in targets:
        T = kin.fk(q_true)
        try:
            q = kin.ik(T, seed, rng=rng)
        except ArmError:
            continue
        solved += 1
        T_q = kin.fk(q)
        assert np.all(q >= kin.q_min) and np.all(q <= kin.q_max)
        assert np.linalg.norm(T_q[:3, 3] - T[:3, 3]) <= 1e-4
        assert np.linalg.norm(pin.log3(T_q[:3, :3].T @ T[:3, :3])) <= 1e-3
    assert solved / len(targets) >= 0.99


def test_ik_warm_start_stays_near_the_seed(kin):
    rng = np.random.default_rng(3)
    q_true = panda().q_ready + rng.normal(0, 0.1, kin.dof)
    q = kin.ik(kin.fk(q_true), q_true + 0.02, restarts=0)
    assert np.abs(q - q_true).max() < 0.05


def test_unreachable_pose_raises_with_the_position_error(kin):
    with pytest.raises(ArmError, match=r"target pose unreachable.*position error \d+\.\d mm"):
        kin.ik(_pose([2.0, 0.0, 0.5], np.eye(3)), panda().q_ready, rng=np.random.default_rng(0))
    for bad in (np.full((4, 4), np.nan), np.diag([2.0, 1, 1, 1]), np.diag([-1.0, 1, 1, 1]), np.eye(3)):
        with pytest.raises(ArmError, match="finite 4x4 pose with a rotation matrix"):
            kin.ik(bad, panda().q_ready)


def test_solve_path_is_continuous_and_names_the_unreachable_waypoint(kin):
    q0 = panda().q_ready
    T0 = kin.fk(q0)
    poses = [_pose(T0[:3, 3] + [0.0, 0.0, -d], T0[:3, :3]) for d in np.linspace(0, 0.2, 21)]
    qs = kin.solve_path(poses, q0)
    assert qs.shape == (21, 7)
    assert np.abs(np.diff(qs, axis=0)).max() < 0.1
    for q, T in zip(qs, poses, strict=True):
        assert np.allclose(kin.fk(q)[:3, 3], T[:3, 3], atol=1e-4)
    far = [_pose(T0[:3, 3] + [d, 0.0, 0.0], T0[:3, :3]) for d in np.linspace(0, 1.0, 51)]
    with pytest.raises(ArmError, match=r"path waypoint (\d+) of 51 is not reachable") as error:
        kin.solve_path(far, q0)
    assert 10 < int(error.value.args[0].split()[2]) < 51  # the arm reaches about 0.85 m
    twist = pin.exp3(np.array([-1.5, 0.0, 0.0]))  # turn the hand 1.5 rad about its approach axis (+x)
    spread = [T0, _pose(T0[:3, 3], twist @ T0[:3, :3])]
    with pytest.raises(ArmError, match="path waypoint 1 of 2 needs joint panda_joint. to jump"):
        kin.solve_path(spread, q0)


def test_bad_models_raise_actionable_errors(tmp_path):
    robot = panda()
    with pytest.raises(ArmError, match="tool frame 'no_such_frame'"):
        Kinematics.from_urdf(robot.urdf, "no_such_frame", robot.finger_joints)
    with pytest.raises(ArmError, match="does not exist"):
        Kinematics.from_urdf(tmp_path / "missing.urdf", robot.tool_frame)
    with pytest.raises(ArmError, match="joints to lock"):
        Kinematics.from_urdf(robot.urdf, robot.tool_frame, ["finger_typo"])


def _null_direction(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """The Panda's one self-motion direction at q (unit joint vector that leaves the tool pose unchanged)."""
    return np.linalg.svd(kin.jacobian(q))[2][-1]


def test_ik_prefers_solutions_toward_the_rest_posture(kin):
    q0 = panda().q_ready
    n = _null_direction(kin, q0)
    T = kin.fk(q0)
    T[0, 3] += 0.02
    q_plus = kin.ik(T, q0, q_rest=q0 + 0.8 * n)
    q_minus = kin.ik(T, q0, q_rest=q0 - 0.8 * n)
    for q in (q_plus, q_minus):
        assert np.linalg.norm(kin.fk(q)[:3, 3] - T[:3, 3]) <= 1e-4
    assert (q_plus - q_minus) @ n > 0.04  # same pose, redundancy pulled apart along the self-motion


def test_solve_path_around_closed_loops_does_not_drift(kin):
    q0 = panda().q_ready
    T0 = kin.fk(q0)
    loop = [_pose(T0[:3, 3] + 0.1 * np.array([np.cos(a) - 1, 0.0, np.sin(a)]), T0[:3, :3])
            for a in np.linspace(0.0, 6 * np.pi, 121)]  # three 0.1 m circles in the x-z plane
    qs = kin.solve_path(loop, q0)
    after_loop = [np.abs(qs[i] - q0).max() for i in (40, 80, 120)]
    assert max(after_loop) < 0.25  # pure least squares drifts ~0.19 rad more every loop
    assert after_loop[2] - after_loop[0] < 0.03


def test_track_moves_within_the_step_limit_or_says_why(kin):
    q0 = panda().q_ready
    max_step = kin.v_max * 0.002  # one 2 ms tick at the velocity limits
    T = kin.fk(q0)
    T[:3, 3] += [-2e-4, 1e-4, 0.0]
    q = kin.track(T, q0, max_step, q0, posture_gain=0.002)
    assert np.all(np.abs(q - q0) < max_step)
    assert np.linalg.norm(kin.fk(q)[:3, 3] - T[:3, 3]) <= 1e-6
    T[:3, 3] += [-0.05, 0.0, 0.0]  # 5 cm in one tick: would need a jump the safety layer rejects
    with pytest.raises(ArmError, match=r"^ik: the tool pose needs joint panda_joint\d at its velocity limit"):
        kin.track(T, q0, max_step, q0, posture_gain=0.002)


def test_near_singular_targets_give_finite_bounded_steps(kin):
    sigma = np.linalg.svd(kin.jacobian(Q_SINGULAR), compute_uv=False)
    assert sigma[-1] < 1e-3 * sigma[0]
    T_singular = kin.fk(Q_SINGULAR)
    q = kin.ik(T_singular, panda().q_ready)  # reached, from a configuration away from the singularity
    assert np.all(np.isfinite(q)) and np.linalg.norm(kin.fk(q)[:3, 3] - T_singular[:3, 3]) <= 1e-4

    U = np.linalg.svd(kin.jacobian(Q_SINGULAR))[0]
    lost = U[:3, -1] / np.linalg.norm(U[:3, -1])  # the tool direction the arm cannot move in
    T = T_singular.copy()
    T[:3, 3] += 2e-4 * lost
    max_step = kin.v_max * 0.002
    with pytest.raises(ArmError, match=r"^ik: the tool pose (is not reached|needs joint)"):  # no spinning
        kin.track(T, Q_SINGULAR, max_step, Q_SINGULAR, posture_gain=0.002)
    for direction in (lost, -lost):
        T = T_singular.copy()
        T[:3, 3] += 0.01 * direction
        q = kin.ik(T, Q_SINGULAR, restarts=0)
        assert np.all(np.isfinite(q)) and np.abs(q - Q_SINGULAR).max() < 0.5
