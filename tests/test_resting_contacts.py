"""Parts resting on something fixed when closed (sim_fallback/resting.py): such pairs never collide, so a gripper
finger stalled on the part's handle presses with the force commanded, as on any other object."""

from pathlib import Path

import numpy as np
import pybullet as pb
from partnet_objects import Front, write_object
from scipy.spatial.transform import Rotation

from sim_fallback.arm import SimArm
from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.partnet import load_partnet
from sim_fallback.resting import REST_CONTACT_M, release_resting_contacts
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

GRIP_FORCE_N = 40.0


def _drawer_on_slab(client: int, T_tool: np.ndarray, folder: Path, gap_m: float) -> tuple[int, int]:
    """A drawer sliding out of the fingers (along -z of the tool) whose bar lies 12 mm off the grip centre, so only
    one finger reaches it, and whose box stands `gap_m` above a static slab (along -x of the tool). (drawer, slab)."""
    urdf = folder / "drawer.urdf"
    urdf.write_text("""<?xml version="1.0"?>
<robot name="drawer">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>
    <collision><origin xyz="0 0 0.3"/><geometry><box size="0.03 0.03 0.02"/></geometry></collision>
  </link>
  <link name="drawer">
    <inertial><origin xyz="0 0 0.1"/><mass value="4"/>
      <inertia ixx="0.05" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
    <collision><origin xyz="0 0.012 0"/><geometry><box size="0.12 0.011 0.011"/></geometry></collision>
    <collision><origin xyz="-0.1 0 0.12"/><geometry><box size="0.04 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="drawer"/><axis xyz="0 0 -1"/>
    <limit lower="0" upper="0.3" effort="1000" velocity="10"/>
  </joint>
</robot>
""")
    quaternion = Rotation.from_matrix(T_tool[:3, :3]).as_quat().tolist()
    drawer = pb.loadURDF(str(urdf), T_tool[:3, 3].tolist(), quaternion, useFixedBase=True, physicsClientId=client)
    pb.setJointMotorControl2(drawer, 0, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=8.0, physicsClientId=client)
    under_box = T_tool[:3, 3] + T_tool[:3, :3] @ np.array([-0.12 - gap_m - 0.02, 0.0, 0.12])
    shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.02, 0.15, 0.15], physicsClientId=client)
    slab = pb.createMultiBody(0, shape, basePosition=under_box.tolist(), baseOrientation=quaternion,
                              physicsClientId=client)
    return drawer, slab


def test_a_finger_stalled_on_a_part_resting_on_a_slab_presses_the_commanded_force(tmp_path):
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm = SimArm(world)
        drawer, slab = _drawer_on_slab(world.client, arm.kin.fk(arm.state().q), tmp_path, gap_m=0.0)
        assert release_resting_contacts(world.client, [drawer, slab]) == [(drawer, 0, slab, -1)]
        arm.set_gripper(0.0, GRIP_FORCE_N)
        for _ in range(240):
            arm.sync()
        robot, fingers = world.robot_id, [world.robot_joints[n] for n in world.robot_spec.finger_joints]
        pressed = [sum(c[9] for c in pb.getContactPoints(robot, drawer, f, 0, physicsClientId=world.client))
                   for f in fingers]
        assert max(pressed) > 0.9 * GRIP_FORCE_N  # the finger on the bar: its full force, not ~2 N
        assert min(pressed) == 0.0  # the other closed past the bar


def test_only_moving_links_touching_fixed_ones_are_released(tmp_path):
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm = SimArm(world)
        T = arm.kin.fk(arm.state().q)
        clear, clear_slab = _drawer_on_slab(world.client, T, tmp_path, gap_m=0.01)
        assert release_resting_contacts(world.client, [clear, clear_slab]) == []
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.05, 0.05, 0.05], physicsClientId=world.client)
        on_base = pb.createMultiBody(0, shape, basePosition=(T[:3, 3] + T[:3, 2] * 0.36).tolist(),
                                     physicsClientId=world.client)  # touches the drawer's fixed base only
        assert release_resting_contacts(world.client, [clear, on_base]) == []


def test_a_partnet_drawer_flush_with_its_body_bottom_does_not_rub_on_what_the_body_stands_on(tmp_path):
    """A box with one tall drawer, small enough to stand on the counter: the drawer's front reaches the counter."""
    flush = Front("drawer", (-0.48, 0.48), (-0.6, 0.58), label="drawer")
    write_object(tmp_path / "1", fronts=(flush,), category="Microwave")
    furniture = load_partnet(tmp_path / "1")
    with SimWorld(KitchenScenario.make("drawer", 0, "train", target=furniture)) as world:
        c, body, link = world.client, world.cabinet_id, world.cabinet_joint
        assert pb.getClosestPoints(body, world.statics_id, REST_CONTACT_M, linkIndexA=link, physicsClientId=c)
        world.clock.step(5)
        assert not pb.getContactPoints(body, world.statics_id, link, physicsClientId=c)
