"""A simulated Franka Panda behind the `Arm` protocol: joint position control, a gripper, a grasp that slips.

Control: PyBullet POSITION_CONTROL (a velocity constraint with position and velocity gains) limited to
the URDF joint efforts; `control_period_s` = 1/240 s, one physics step per `sync()`.

Grasp: when the closing fingers both touch the handle, the hand holds it as a parallel gripper does
(sim_fallback/grip.py): the handle turns in the fingers about its bar, slides along the bar past the grip's
friction (2 pads x FINGER_FRICTION x the gripping force, or `grasp_force_limit_n` when set) and slips out
past it, after which the fingers close on nothing and the measured width drops. Opening releases it.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

from drivers.arm.base import GRIP_FORCE_N, Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.errors import ArmError
from sim_fallback.grip import Grip
from sim_fallback.world import SimWorld

FINGER_FRICTION = 1.0  # rubber finger pads on a handle
POSITION_GAIN, VELOCITY_GAIN = 0.3, 1.0  # PyBullet POSITION_CONTROL gains at 240 Hz
FINGER_SPEED_M_S = 0.1


class SimArm(Arm):
    """The Panda of a `SimWorld`. Keeps the world's physics clock and body ids, not the world itself.

    kin: the arm's kinematics (default `Kinematics.panda()`, the model the real arm uses);
    guard: the safety check every `command()` goes through (default: the Panda's `SafetyLimits`);
    grasp_force_limit_n: the grip's friction force (N) past which it slides and slips (None: from the gripping
    force).
    """

    control_period_s = 1.0 / 240

    def __init__(
        self,
        world: SimWorld,
        kin: Kinematics | None = None,
        guard: SafetyGuard | None = None,
        grasp_force_limit_n: float | None = None,
    ) -> None:
        self._clock = world.clock
        self._client, self._robot = world.client, world.robot_id
        self._cabinet, self._handle_link = world.cabinet_id, world.handle_link
        spec = world.robot_spec
        self._spec = spec
        self.kin = kin or Kinematics.panda()
        self.guard = guard or SafetyGuard(SafetyLimits.for_robot(spec, self.kin), spec.arm_joints)
        self.grasp_force_limit_n = grasp_force_limit_n
        self._joints = [world.robot_joints[name] for name in spec.arm_joints]
        self._fingers = [world.robot_joints[name] for name in spec.finger_joints]
        self._hand = world.robot_joints["panda_hand_joint"]  # the hand link's index = its joint's index
        info = [pb.getJointInfo(self._robot, j, physicsClientId=self._client) for j in self._joints]
        self._effort = [i[10] for i in info]  # URDF effort limits, N m
        self._q_prev_cmd = np.zeros(len(self._joints))
        self._dq_prev_cmd = np.zeros(len(self._joints))
        self._gripper_target = spec.gripper_max_width_m
        self._grip: Grip | None = None
        self._grip_force_n = GRIP_FORCE_N
        self._may_grip = False  # set by a gripper command, cleared by a grip: a slipped grasp stays slipped
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

    def set_gripper(self, width_m: float, force_n: float = GRIP_FORCE_N) -> None:
        """Both fingers (PyBullet ignores <mimic>) move to width/2 each, pushing with at most `force_n`."""
        width = float(np.clip(width_m, 0.0, self._spec.gripper_max_width_m))
        if width > self._gripper_target:
            self._release()
        self._gripper_target, self._grip_force_n = width, float(force_n)
        self._may_grip = self._grip is None
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
        if self._grip is None:
            if self._may_grip and self._closing_on_handle():
                self._make_grip()
        elif not self._grip.update():
            self._grip = None

    def _contacts(self) -> list[list]:
        robot, cabinet, handle, c = self._robot, self._cabinet, self._handle_link, self._client
        return [pb.getContactPoints(robot, cabinet, f, handle, physicsClientId=c) for f in self._fingers]

    def _closing_on_handle(self) -> bool:
        if self._gripper_target >= self.state().gripper_width_m - 1e-4:
            return False
        return all(self._contacts())

    def _make_grip(self) -> None:
        """Both fingers touch the handle: hold it at the middle of their contacts, along the tool's x (the bar)."""
        centre = np.mean([np.mean([c[6] for c in finger], axis=0) for finger in self._contacts()], axis=0)
        hand = pb.getLinkState(self._robot, self._hand, physicsClientId=self._client)
        bar = np.asarray(pb.getMatrixFromQuaternion(hand[5])).reshape(3, 3)[:, 0]  # the hand frame's x axis
        limit = self.grasp_force_limit_n if self.grasp_force_limit_n is not None else \
            2 * FINGER_FRICTION * self._grip_force_n
        self._grip = Grip(self._client, self._robot, self._hand, self._cabinet, self._handle_link, centre, bar, limit)
        self._may_grip = False

    def _release(self) -> None:
        if self._grip is not None:
            self._grip.release()
            self._grip = None
