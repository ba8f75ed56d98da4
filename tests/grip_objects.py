"""Small articulated objects the grip tests build between the open fingers of the simulated Panda: a fixed base
beyond the fingertips and one moving link, a handle, on a joint through the grip centre. Frames: the tool's (x along
the fingers' pads, y the closing direction, z the approach)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as pb

HANDLES = {
    "bar": '<box size="0.12 0.012 0.012"/>',  # a bar along the pads, 12 mm square
    "knob": '<sphere radius="0.015"/>',  # a round knob
}
JOINTS = {
    "slide": ("prismatic", "0 0 -1"),  # pulled out of the fingers: positive opening
    "twist": ("revolute", "0 1 0"),  # turned about the closing direction
}


def object_at_tool(client: int, T_tool: np.ndarray, handle: str, joint: str, folder: Path) -> int:
    """Load an object whose `handle` ("bar" or "knob") lies between the fingers at tool pose `T_tool` (4x4), on a
    `joint` ("slide" or "twist") through the grip centre; its joint's default motor off. The body id."""
    kind, axis = JOINTS[joint]
    urdf = folder / f"{handle}_{joint}.urdf"
    urdf.write_text(f"""<?xml version="1.0"?>
<robot name="{handle}_{joint}">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.03 0.03 0.02"/></geometry></collision>
  </link>
  <link name="handle">
    <inertial><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <collision><geometry>{HANDLES[handle]}</geometry></collision>
  </link>
  <joint name="joint" type="{kind}">
    <parent link="base"/><child link="handle"/><axis xyz="{axis}"/>
    <limit lower="-3.2" upper="3.2" effort="1000" velocity="10"/>
  </joint>
</robot>
""")
    quaternion = _quaternion(T_tool[:3, :3])
    body = pb.loadURDF(str(urdf), T_tool[:3, 3].tolist(), quaternion, useFixedBase=True, physicsClientId=client)
    pb.setJointMotorControl2(body, 0, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0, physicsClientId=client)
    pb.changeDynamics(body, -1, activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=client)
    return body


def _quaternion(R: np.ndarray) -> list[float]:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat().tolist()
