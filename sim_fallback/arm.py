"""The simulated world's arm (the Franka Panda, or the robot config's arm the world stands) behind the `Arm`
protocol: joint position control, a gripper, a grasp that slips.

Control: PyBullet POSITION_CONTROL (a velocity constraint with position and velocity gains) limited to
the URDF joint efforts; `control_period_s` = 1/240 s, one physics step per `sync()`.

Torques: PyBullet's applied joint torques, exact, or as a Damiao motor measures them (`torque_sensing`,
sim_fallback/torque_sensing.py), one reading per physics step.

Gripper: the robot's finger joints (prismatic or hinged) set from the opening by its `finger_joint_per_m`, each
pushing with its share of the gripping force; the measured opening is read back from them the same way.

Grasp: when the closing fingers both touch one link of anything, the hand holds it as a parallel gripper does
(sim_fallback/grip.py): a bar turns in the fingers about its length, a knob also about the other axes; the object
slides through the fingers past the grip's friction (2 pads x `pad_friction` x the gripping force, or
`grasp_force_limit_n` when set) and slips out past it, after which the fingers close on nothing and the measured
width drops. Opening releases it.
"""

from __future__ import annotations

import numpy as np
import pybullet as pb

from drivers.arm.base import GRIP_FORCE_N, Arm, ArmState
from drivers.arm.kinematics import Kinematics
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.errors import ArmError
from sim_fallback.grip import Grip, grasped_link, make_probe
from sim_fallback.torque_sensing import TorqueSensing
from sim_fallback.world import SimWorld

PAD_FRICTION = 0.8  # rubber finger pads on a lacquered or metal handle: 0.4-0.8 (episodes draw theirs)
POSITION_GAIN, VELOCITY_GAIN = 0.3, 1.0  # PyBullet POSITION_CONTROL gains at 240 Hz
FINGER_SPEED_M_S = 0.1


class SimArm(Arm):
    """The arm of a `SimWorld`. Keeps the world's physics clock and body ids, not the world itself.

    kin: the arm's kinematics (default `Kinematics.panda()`, the model the real arm uses);
    guard: the safety check every `command()` goes through (default: the Panda's `SafetyLimits`);
    grasp_force_limit_n: the grip's friction force (N) past which it slides and slips (None: from the gripping
    force and `pad_friction`, the pads' friction coefficient);
    torque_sensing: what turns the simulated joint torques into measured ones (None: exact).
    """

    control_period_s = 1.0 / 240

    def __init__(
        self,
        world: SimWorld,
        kin: Kinematics | None = None,
        guard: SafetyGuard | None = None,
        grasp_force_limit_n: float | None = None,
        pad_friction: float = PAD_FRICTION,
        torque_sensing: TorqueSensing | None = None,
    ) -> None:
        self._clock = world.clock
        self._client, self._robot = world.client, world.robot_id
        spec = world.robot_spec
        self._spec = spec
        self.kin = kin or Kinematics.panda()
        self.guard = guard or SafetyGuard(SafetyLimits.for_robot(spec, self.kin), spec.arm_joints)
        self.grasp_force_limit_n = grasp_force_limit_n
        self.pad_friction = float(pad_friction)
        self.torque_sensing = torque_sensing
        self._sensed: tuple[int, np.ndarray] | None = None  # (physics step, measured torques)
        self._joints = [world.robot_joints[name] for name in spec.arm_joints]
        self._fingers = [world.robot_joints[name] for name in spec.finger_joints]
        # the hand: the link the fingers hang from (a link's index is its joint's)
        self._hand = pb.getJointInfo(self._robot, self._fingers[0], physicsClientId=self._client)[16]
        for finger in self._fingers:  # the grip's friction model holds what the pads hold, not the contacts
            pb.changeDynamics(self._robot, finger, lateralFriction=0.0, spinningFriction=0.0,
                              physicsClientId=self._client)
        info = [pb.getJointInfo(self._robot, j, physicsClientId=self._client) for j in self._joints]
        self._effort = [i[10] for i in info]  # URDF effort limits, N m
        self._q_prev_cmd = np.zeros(len(self._joints))
        self._dq_prev_cmd = np.zeros(len(self._joints))
        self._gripper_target = spec.gripper_max_width_m
        self._grip: Grip | None = None
        self._probe = make_probe(self._client)
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
            tau=self._measured(np.array([s[3] for s in arm])),
            gripper_width_m=self._spec.gripper_width([s[0] for s in states[len(self._joints):]]),
        )

    def _measured(self, tau: np.ndarray) -> np.ndarray:
        """The torques as the arm measures them: one reading per physics step, however often it is asked."""
        if self.torque_sensing is None:
            return tau
        if self._sensed is None or self._sensed[0] != self._clock.steps:
            self._sensed = (self._clock.steps, self.torque_sensing.measure(tau, self._clock.time))
        return self._sensed[1].copy()

    def commanded_q(self) -> np.ndarray:
        return self._q_prev_cmd.copy()

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
        """Every finger (PyBullet ignores <mimic>) moves to its position at the opening, pushing so that the fingers
        squeeze with at most `force_n` (virtual work: a finger of k joint units per metre of opening pushes with
        force / (2 |k|), the Panda's prismatic fingers with `force_n` each) at FINGER_SPEED_M_S of opening."""
        width = float(np.clip(width_m, 0.0, self._spec.gripper_max_width_m))
        if width > self._gripper_target:
            self._release()
        self._gripper_target, self._grip_force_n = width, float(force_n)
        self._may_grip = self._grip is None
        targets = self._spec.finger_positions(width)
        for finger, target, k in zip(self._fingers, targets, self._spec.finger_joint_per_m, strict=True):
            pb.setJointMotorControl2(self._robot, finger, pb.POSITION_CONTROL, targetPosition=target,
                                     force=force_n / (2 * abs(k)), maxVelocity=FINGER_SPEED_M_S * 2 * abs(k),
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
            if self._may_grip and self._closing():
                self._make_grip()
        elif not self._grip.update():
            self._grip = None

    def _closing(self) -> bool:
        return self._gripper_target < self.state().gripper_width_m - 1e-4

    def _make_grip(self) -> None:
        """Both fingers touch one link: hold it where they touch (sim_fallback/grip.py)."""
        held = grasped_link(self._client, self._robot, self._fingers)
        if held is None:
            return
        limit = self.grasp_force_limit_n if self.grasp_force_limit_n is not None else \
            2 * self.pad_friction * self._grip_force_n
        self._grip = Grip(self._client, self._robot, self._hand, self._fingers, *held, limit, self._probe)
        self._may_grip = False

    def _release(self) -> None:
        if self._grip is not None:
            self._grip.release()
            self._grip = None
