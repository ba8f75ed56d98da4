"""A simulated Franka Panda behind the `Arm` protocol: joint position control, a gripper, a grasp that slips.

Control: PyBullet POSITION_CONTROL (a velocity constraint with position and velocity gains) limited to
the URDF joint efforts; `control_period_s` = 1/240 s, one physics step per `sync()`.

Grasp: when the closing fingers both touch the handle, a fixed constraint welds the hand to it with a
force limit (`grasp_force_limit_n`); PyBullet then lets the weld stretch under larger loads, and once
the hand has drifted `SLIP_DISTANCE_M` from the handle the weld is released (a slip: the fingers keep
closing and the measured gripper width drops, as on a real gripper). Opening the gripper releases it.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

from drivers.arm.base import Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.errors import ArmError
from sim_fallback.world import SimWorld

GRASP_FORCE_LIMIT_N = 90.0  # a firm two-finger grasp on a bar handle
SLIP_DISTANCE_M = 0.01  # hand-to-handle drift at which the weld lets go
POSITION_GAIN, VELOCITY_GAIN = 0.3, 1.0  # PyBullet POSITION_CONTROL gains at 240 Hz
FINGER_SPEED_M_S = 0.1


class SimArm(Arm):
    """The Panda of a `SimWorld`. Keeps the world's physics clock and body ids, not the world itself.

    kin: the arm's kinematics (default `Kinematics.panda()`, the model the real arm uses);
    guard: the safety check every `command()` goes through (default: the Panda's `SafetyLimits`);
    grasp_force_limit_n: the weld's force limit, above which the grasp slips.
    """

    control_period_s = 1.0 / 240

    def __init__(
        self,
        world: SimWorld,
        kin: Kinematics | None = None,
        guard: SafetyGuard | None = None,
        grasp_force_limit_n: float = GRASP_FORCE_LIMIT_N,
    ) -> None:
        self._clock = world.clock
        self._client, self._robot = world.client, world.robot_id
        self._cabinet, self._handle_link = world.cabinet_id, world.handle_link
        spec = world.robot_spec
        self._spec = spec
        self.kin = kin or Kinematics.panda()
        self.guard = guard or SafetyGuard(SafetyLimits.for_robot(spec, self.kin), spec.arm_joints)
        self.grasp_force_limit_n = float(grasp_force_limit_n)
        self._joints = [world.robot_joints[name] for name in spec.arm_joints]
        self._fingers = [world.robot_joints[name] for name in spec.finger_joints]
        self._hand = world.robot_joints["panda_hand_joint"]  # the hand link's index = its joint's index
        info = [pb.getJointInfo(self._robot, j, physicsClientId=self._client) for j in self._joints]
        self._effort = [i[10] for i in info]  # URDF effort limits, N m
        self._q_prev_cmd = np.zeros(len(self._joints))
        self._dq_prev_cmd = np.zeros(len(self._joints))
        self._gripper_target = spec.gripper_max_width_m
        self._weld: int | None = None
        self._may_weld = False  # set by a gripper command, cleared by a weld: a slipped grasp stays slipped
        self._weld_child_pos = np.zeros(3)
        self._clock.add_hook(self._after_step)
        self.connect()

    @property
    def joint_names(self) -> list[str]:
        return list(self._spec.arm_joints)

    def connect(self) -> None:
        """Enable the motors holding the current position and gripper opening (idempotent)."""
        self._hold(self.state().q)
        self.set_gripper(self._gripper_target)

    def state(self) -> ArmState:
        states = pb.getJointStates(self._robot, self._joints + self._fingers, physicsClientId=self._client)
        arm = states[: len(self._joints)]
        return ArmState(
            t=self._clock.time,
            q=np.array([s[0] for s in arm]),
            dq=np.array([s[1] for s in arm]),
            tau=np.array([s[3] for s in arm]),
            gripper_width_m=float(sum(s[0] for s in states[len(self._joints):])),
        )

    def command(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        q = np.asarray(q, float)
        dq = np.zeros_like(q) if dq is None else np.asarray(dq, float)
        try:
            self.guard.check(q, dq, self._q_prev_cmd, self.control_period_s, self.kin.fk(q)[:3, 3],
                              self._dq_prev_cmd, self.state().q)
        except ArmError:
            self.stop()
            raise
        self._send(q, dq)

    def sync(self) -> None:
        self._clock.step(1)

    def set_gripper(self, width_m: float, force_n: float = 40.0) -> None:
        """Both fingers (PyBullet ignores <mimic>) move to width/2 each, pushing with at most `force_n`."""
        width = float(np.clip(width_m, 0.0, self._spec.gripper_max_width_m))
        if width > self._gripper_target:
            self._release()
        self._gripper_target = width
        self._may_weld = self._weld is None
        for finger in self._fingers:
            pb.setJointMotorControl2(self._robot, finger, pb.POSITION_CONTROL, targetPosition=width / 2,
                                     force=force_n, maxVelocity=FINGER_SPEED_M_S,
                                     physicsClientId=self._client)

    def stop(self) -> None:
        """Hold the measured position (idempotent; never raises, also after the world is closed)."""
        try:
            self._hold(self.state().q)
        except pb.error:
            pass

    def _hold(self, q: np.ndarray) -> None:
        self._send(q, np.zeros_like(q))

    def _send(self, q: np.ndarray, dq: np.ndarray) -> None:
        n = len(self._joints)
        pb.setJointMotorControlArray(
            self._robot, self._joints, pb.POSITION_CONTROL, targetPositions=q.tolist(),
            targetVelocities=dq.tolist(), forces=self._effort, positionGains=[POSITION_GAIN] * n,
            velocityGains=[VELOCITY_GAIN] * n, physicsClientId=self._client,
        )
        self._q_prev_cmd, self._dq_prev_cmd = q.copy(), dq.copy()

    # --- grasp ------------------------------------------------------------------------------------------

    def _after_step(self) -> None:
        if self._weld is None:
            if self._may_weld and self._closing_on_handle():
                self._make_weld()
        elif np.linalg.norm(self._hand_in_handle() - self._weld_child_pos) > SLIP_DISTANCE_M:
            self._release()

    def _closing_on_handle(self) -> bool:
        if self._gripper_target >= self.state().gripper_width_m - 1e-4:
            return False
        robot, cabinet, handle, c = self._robot, self._cabinet, self._handle_link, self._client
        return all(pb.getContactPoints(robot, cabinet, f, handle, physicsClientId=c) for f in self._fingers)

    def _com_pose(self, body: int, link: int) -> tuple:
        state = pb.getLinkState(body, link, physicsClientId=self._client)
        return state[0], state[1]

    def _hand_in_handle(self) -> np.ndarray:
        """The hand's centre of mass in the handle's centre-of-mass frame."""
        handle = self._com_pose(self._cabinet, self._handle_link)
        hand = self._com_pose(self._robot, self._hand)
        inv_pos, inv_orn = pb.invertTransform(*handle)
        pos, _ = pb.multiplyTransforms(inv_pos, inv_orn, *hand)
        return np.array(pos)

    def _make_weld(self) -> None:
        handle = self._com_pose(self._cabinet, self._handle_link)
        hand = self._com_pose(self._robot, self._hand)
        inv_pos, inv_orn = pb.invertTransform(*handle)
        pos, orn = pb.multiplyTransforms(inv_pos, inv_orn, *hand)
        self._weld = pb.createConstraint(
            self._robot, self._hand, self._cabinet, self._handle_link, pb.JOINT_FIXED, [0, 0, 0],
            parentFramePosition=[0, 0, 0], childFramePosition=pos, childFrameOrientation=orn,
            physicsClientId=self._client,
        )
        pb.changeConstraint(self._weld, maxForce=self.grasp_force_limit_n, physicsClientId=self._client)
        self._weld_child_pos = np.array(pos)
        self._may_weld = False

    def _release(self) -> None:
        if self._weld is not None:
            pb.removeConstraint(self._weld, physicsClientId=self._client)
            self._weld = None
