"""OpenArm out of the box (`--robot openarm`): the vendor's description as the project ships it (URDF, meshes,
licence), the same kinematics in Pinocchio and PyBullet, its motors found over CAN FD on the simulated bus, bring-up
moves, and the conversion script on a small model in the vendor's MJCF layout."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from drivers.arm.robot_config import load_robot_config
from sim_fallback.devices import sim_can_arm
from tests.cli_run import run

ROOT = Path(__file__).resolve().parents[1]
OPENARM = load_robot_config("openarm")
VENDOR_RANGES = {  # openarm-mujoco 2.3.0, v2/openarm_bimanual.xml, the right arm's joints
    "openarm_right_joint1": (-1.3963, 3.4907), "openarm_right_joint2": (-0.17453, 3.3161),
    "openarm_right_joint3": (-1.5708, 1.5708), "openarm_right_joint4": (0.0, 2.4435),
    "openarm_right_joint5": (-1.5708, 1.5708), "openarm_right_joint6": (-0.7854, 0.7854),
    "openarm_right_joint7": (-1.5708, 1.5708),
}


def test_the_shipped_description_keeps_the_vendors_licence_and_joints():
    folder = OPENARM.urdf_path().parent
    assert "Apache License" in (folder / "LICENSE").read_text() and "Enactic" in (folder / "NOTICE").read_text()
    kin = OPENARM.kinematics()
    assert kin.joint_names == list(VENDOR_RANGES) == OPENARM.joint_names
    assert np.allclose(np.c_[kin.q_min, kin.q_max], list(VENDOR_RANGES.values()))
    assert [j.motor for j in OPENARM.joints] == ["DM8009"] * 2 + ["DM4340"] * 2 + ["DM4310"] * 3
    assert OPENARM.gripper.motor == "DM4310" and [m.can_id for m in OPENARM.motors] == list(range(1, 9))
    assert OPENARM.can.fd and (OPENARM.can.bitrate, OPENARM.can.data_bitrate) == (1_000_000, 5_000_000)


def test_pinocchio_and_pybullet_agree_on_the_tool_pose():
    kin = OPENARM.kinematics()
    client = pb.connect(pb.DIRECT)
    try:
        robot = pb.loadURDF(str(OPENARM.urdf_path()), useFixedBase=True, physicsClientId=client)
        names = {pb.getJointInfo(robot, j, physicsClientId=client)[1].decode(): j
                 for j in range(pb.getNumJoints(robot, physicsClientId=client))}
        tcp = next(j for j in range(pb.getNumJoints(robot, physicsClientId=client))
                   if pb.getJointInfo(robot, j, physicsClientId=client)[12].decode() == OPENARM.tool_frame)
        rng = np.random.default_rng(3)
        for _ in range(5):
            q = rng.uniform(kin.q_min, kin.q_max)
            for name, value in zip(kin.joint_names, q, strict=True):
                pb.resetJointState(robot, names[name], value, physicsClientId=client)
            position, orientation = pb.getLinkState(robot, tcp, computeForwardKinematics=True,
                                                    physicsClientId=client)[4:6]
            T = kin.fk(q)
            assert np.allclose(T[:3, 3], position, atol=1e-6)
            assert np.allclose(T[:3, :3], np.reshape(pb.getMatrixFromQuaternion(orientation), (3, 3)), atol=1e-6)
    finally:
        pb.disconnect(client)


def test_q_ready_holds_the_tool_forward_and_level():
    T = OPENARM.kinematics().fk(np.array(OPENARM.q_ready))
    assert np.allclose(T[:3, 3], [0.35, 0.0, 0.60], atol=2e-3)
    assert T[:3, 2] @ [1, 0, 0] > 0.999  # the approach (z) along +x
    assert abs(T[:3, 0] @ [0, 0, 1]) > 0.999  # the pads' width (x) vertical: a vertical bar between the fingers


def test_the_body_opens_its_hinged_fingers_with_the_gripper():
    from drivers.arm.body import RobotBody

    body = RobotBody.from_robot(OPENARM)
    q = np.array(OPENARM.q_ready)
    closed, opened = body.links(q, 0.0), body.links(q, OPENARM.gripper.max_width_m)
    moved = [np.abs(a - b).max() for a, b in zip(closed, opened, strict=True)]
    assert max(moved) > 0.05 and sum(m > 1e-6 for m in moved) == 8  # the two fingers' four meshes each


def test_scan_finds_the_eight_motors_over_can_fd(capsys):
    code, out, _ = run(capsys, "arm", "scan", "--arm", "sim-can", "--robot", "openarm", "--json")
    motors = json.loads(out)["motors"]
    assert code == 0 and [(m["can_id"], m["master_id"]) for m in motors] == [(i, 0x10 + i) for i in range(1, 9)]
    assert all(m["fd"] for m in motors)
    assert [m["t_max"] for m in motors] == [54.0, 54.0, 28.0, 28.0, 10.0, 10.0, 10.0, 10.0]


def test_classic_frames_do_not_reach_motors_on_a_can_fd_bus():
    """The simulated motors speak their bus's protocol: a driver configured for classic CAN gets no answer."""
    classic = OPENARM.model_copy(update={"can": OPENARM.can.model_copy(update={"fd": False})})
    arm, motors = sim_can_arm(classic)
    motors.fd = True
    with pytest.raises(Exception, match="did not answer a parameter read"):
        arm.connect()
    arm.disconnect()


@pytest.mark.parametrize("command", [
    ["status"], ["home", "--yes"], ["jog", "--joint", "openarm_right_joint4", "--delta", "-0.2", "--yes"],
    ["move", "--pose", "0.33", "-0.05", "0.58", "180", "-90", "0", "--yes"],
])
def test_bring_up_commands_run_the_openarm(capsys, command):
    code, out, err = run(capsys, "arm", *command, "--arm", "sim-can", "--robot", "openarm", "--json")
    assert code == 0, err
    data = json.loads(out)
    if command[0] != "status":
        assert data["max_joint_error_rad"] <= 0.01
    else:
        assert [m["timeout_ms"] for m in data["motors"]] == [100.0] * 8


def test_the_openarm_bus_off_case_ends_with_every_motor_disabled(capsys):
    code, out, _ = run(capsys, "arm", "jog", "--arm", "sim-can", "--robot", "openarm", "--joint",
                       "openarm_right_joint1", "--delta", "0.3", "--yes", "--sim-fault", "bus-off@0.2", "--json")
    data = json.loads(out)
    assert code == 2 and [(m["enabled"], m["status"]) for m in data["motors"]] == [(False, "timed out")] * 8


MJCF = """<mujoco model="tiny">
  <default><default class="robot">
    <default class="motor_DM8009"><joint type="hinge"/></default>
    <default class="motor_DM4310"><joint type="hinge"/><default class="motor_finger"><joint/></default></default>
    <default class="collision"><geom/><default class="fingertip"><geom/></default></default>
  </default></default>
  <asset><mesh name="box_c" file="collision/box.stl"/><mesh name="box_v" file="visual/box.obj"/></asset>
  <worldbody>
    <body name="openarm_right_base_link" pos="0 -0.031 0">
      <geom type="mesh" mesh="box_c" class="collision"/>
      <body name="openarm_right_link1" pos="0 -0.0625 0">
        <inertial pos="0 0 -0.1" mass="1.5" diaginertia="0.01 0.02 0.03"/>
        <joint name="openarm_right_joint1" axis="0 -1 0" range="-1 2" actuatorfrcrange="-40 40"
               class="motor_DM8009"/>
        <geom type="mesh" mesh="box_v" class="visual"/>
        <body name="openarm_right_link2" pos="0 -0.06 0">
          <body name="openarm_right_ee_base_link" pos="0 0 -0.3" quat="0.7071068 0 0 0.7071068">
            <joint name="openarm_right_joint7" axis="1 0 0" range="-1.5 1.5" actuatorfrcrange="-7 7"
                   class="motor_DM4310"/>
            <body name="openarm_right_ee_inner_finger" pos="0 0.01 -0.05">
              <joint name="openarm_right_finger_joint1" axis="-1 0 0" range="-0.7 0" class="motor_finger"/>
              <geom type="mesh" mesh="box_c" class="fingertip"/>
            </body>
            <body name="openarm_right_ee_outer_finger" pos="0 -0.01 -0.05">
              <joint name="openarm_right_finger_joint2" axis="1 0 0" range="-0.7 0" class="motor_finger"/>
              <geom type="mesh" mesh="box_c" class="fingertip"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <equality><joint joint1="openarm_right_finger_joint1" joint2="openarm_right_finger_joint2"/></equality>
</mujoco>
"""


def _box_stl(path: Path) -> None:
    """A binary STL of a 2 x 2 x 4 cm box hanging 4 cm below its origin (12 triangles)."""
    lo, hi = np.array([-0.01, -0.01, -0.04]), np.array([0.01, 0.01, 0.0])
    corners = np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)])
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
             (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    records = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    records["v"] = corners[np.array(faces)]
    path.write_bytes(bytes(80) + len(faces).to_bytes(4, "little") + records.tobytes())


def test_the_conversion_script_writes_a_urdf_that_pinocchio_loads(tmp_path):
    vendor = tmp_path / "vendor"
    (vendor / "v2" / "assets" / "collision").mkdir(parents=True)
    _box_stl(vendor / "v2" / "assets" / "collision" / "box.stl")
    (vendor / "v2" / "openarm_bimanual.xml").write_text(MJCF)
    (vendor / "LICENSE").write_text("Apache License, Version 2.0\n")
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "openarm_urdf.py"), "--mjcf",
                           str(vendor / "v2" / "openarm_bimanual.xml"), "--out", str(out)],
                          capture_output=True, text=True, check=False, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert (out / "LICENSE").read_text().startswith("Apache") and (out / "meshes" / "box.stl").is_file()
    model = pin.buildModelFromUrdf(str(out / "openarm.urdf"))
    assert [model.names[i] for i in range(1, model.njoints)] == [
        "openarm_right_joint1", "openarm_right_joint7", "openarm_right_finger_joint1", "openarm_right_finger_joint2"]
    assert np.allclose(model.lowerPositionLimit[:2], [-1, -1.5]) and np.allclose(model.effortLimit[:2], [40, 7])
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    # the mount at the pedestal's height, the arm hanging over the origin; the grasp frame 1.2 cm above the
    # fingertips' lowest point (5 cm + 4 cm below the hand), its z (the approach) pointing down out of the fingers
    assert np.allclose(data.oMf[model.getFrameId("openarm_right_link1")].translation, [0, -0.0625 + 0.1225, 0.698])
    tcp = data.oMf[model.getFrameId("openarm_right_tcp")]
    assert np.allclose(tcp.translation, [0, 0, 0.698 - 0.3 - 0.09 + 0.012], atol=1e-6)
    assert np.allclose(tcp.rotation[:, 2], [0, 0, -1], atol=1e-6)
    assert "<mimic joint=\"openarm_right_finger_joint1\"" in (out / "openarm.urdf").read_text()
