"""Simulated Damiao motors on a python-can bus (virtual, or Linux vcan): they answer enable / disable / set zero /
clear error / parameter read / refresh / MIT frames with realistic feedback, so the real CAN driver (CanArm)
is tested without hardware.

Motor state comes from one of two backends:
- `IntegratedMotors`: each joint is an inertia with viscous friction driven by the MIT law
  tau = kp (q* - q) + kd (dq* - dq) + tau*, clipped to TMAX, integrated in sub-steps; for a config with
  `gravity_compensation` the enabled joints also carry the gravity of its URDF (`GravityLoad`: the model the
  driver compensates), so that compensation cancels it (a disabled joint rests on its support);
- `PyBulletMotors`: the joints of a `SimArm` (PyBullet position control toward q*, dq* within the URDF efforts;
  gains are not modelled, disabled motors hold still) and its gripper.

Two ways to run: `start()` a thread that answers at once on the wall clock (realtime CanArm), or `step(dt)` from
the arm's `on_cycle` (lockstep: answer, advance one period, reply to MIT frames with the new state). Once closed
(the driver has gone) the motors' clock runs on without commands (`idle`).

Each motor holds a communication timeout (REG_TIMEOUT, written and read back through the parameter frames; 0, the
factory value, never fires): an enabled motor that receives no command (MIT or special frame) for that long
disables itself and reports "communication lost" until enabled again. The motors speak the protocol of the
config's bus: on a CAN FD bus they answer in FD frames (bitrate switch) and cannot read classic ones, and the
other way round.

Fault injection per motor (`MotorFaults`): dropped and delayed frames, silence, a status fault; and for the bus:
`inject_bus_off()` / `inject_error_passive()` (SocketCAN error frames). `schedule(t, action)` runs an injection
once the motors' clock reaches t (sim_fallback/sim_faults.py writes them as text).
"""

from __future__ import annotations

import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field

import can
import numpy as np
import pinocchio as pin

from drivers.arm.can_bus import CAN_ERR_BUSOFF, CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE
from drivers.arm.damiao import (
    PARAM_ID,
    PARAM_READ,
    PARAM_WRITE,
    REFRESH,
    REG_MST_ID,
    REG_PMAX,
    REG_TIMEOUT,
    REG_TMAX,
    REG_VMAX,
    TIMEOUT_UNIT_S,
    FrameError,
    MotorLimits,
    Special,
    Status,
    is_special,
    pack_feedback,
    pack_param_reply,
    unpack_mit,
    unpack_param_reply,
    unpack_param_request,
)
from drivers.arm.robot_config import MotorConfig, RobotConfig

SUBSTEP_S = 2.5e-4
DEFAULT_INERTIA, DEFAULT_FRICTION = 0.05, 0.1  # kg m^2 and N m s / rad at the joint: a small arm link


@dataclass
class MotorFaults:
    """What to break on one motor: drop every n-th reply (or a random share), delay replies, stop answering,
    report a status fault (the motor then disables itself, as a real one does)."""

    drop_every: int = 0
    drop_rate: float = 0.0
    delay_s: float = 0.0
    silent: bool = False
    status: Status | None = None


@dataclass
class SimMotor:
    """One simulated motor's registers, command and state (motor side: rad, rad/s, N m)."""

    config: MotorConfig
    limits: MotorLimits
    enabled: bool = False
    q: float = 0.0
    dq: float = 0.0
    tau: float = 0.0
    command: tuple[float, float, float, float, float] | None = None  # q, dq, kp, kd, tau
    faults: MotorFaults = field(default_factory=MotorFaults)
    replies: int = 0
    mit_frames: int = 0
    timeout_steps: int = 0  # REG_TIMEOUT: 0 = never
    timeout_locked: bool = False  # a firmware that answers a write of REG_TIMEOUT but keeps its value
    last_command_s: float = 0.0  # the motors' clock at the last command it received
    lost: bool = False  # disabled by its communication timeout

    @property
    def status(self) -> Status:
        if self.faults.status is not None:
            return self.faults.status
        if self.lost:
            return Status.COMMUNICATION_LOST
        return Status.ENABLED if self.enabled else Status.DISABLED

    @property
    def timeout_s(self) -> float:
        return self.timeout_steps * TIMEOUT_UNIT_S

    def check_timeout(self, t: float) -> None:
        """Disable itself when enabled and no command came for its communication timeout (motors' clock `t`)."""
        if self.enabled and self.timeout_steps and t - self.last_command_s >= self.timeout_s - 1e-12:
            self.enabled, self.command, self.lost = False, None, True


class GravityLoad:
    """The gravity torque of `config`'s arm (its URDF's inertias, Pinocchio) on each joint's motor, motor side."""

    def __init__(self, config: RobotConfig) -> None:
        self.model = config.kinematics().model
        self.data = self.model.createData()
        self.direction = np.array([j.direction for j in config.joints], float)
        self.zero_offset = np.array([j.zero_offset for j in config.joints], float)

    def __call__(self, q_motor: np.ndarray) -> np.ndarray:
        q = self.direction * q_motor + self.zero_offset
        return self.direction * pin.computeGeneralizedGravity(self.model, self.data, q)


class IntegratedMotors:
    """Joint dynamics integrated from the MIT commands; `gravity` (None: unloaded motors) loads the first joints'
    motors while they are enabled."""

    def __init__(self, inertia: float = DEFAULT_INERTIA, friction: float = DEFAULT_FRICTION,
                 gravity: GravityLoad | None = None) -> None:
        self.inertia, self.friction, self.gravity = inertia, friction, gravity

    def advance(self, motors: list[SimMotor], dt: float) -> None:
        n = max(1, int(np.ceil(dt / SUBSTEP_S)))
        h = dt / n
        loaded = motors[: len(self.gravity.direction)] if self.gravity is not None else []
        for _ in range(n):
            load = self.gravity(np.array([m.q for m in loaded])) if loaded else ()
            for i, m in enumerate(motors):
                tau = 0.0
                if m.enabled and m.command is not None:
                    q_ref, dq_ref, kp, kd, tau_ff = m.command
                    tau = kp * (q_ref - m.q) + kd * (dq_ref - m.dq) + tau_ff
                    tau = min(max(tau, -m.limits.t_max), m.limits.t_max)
                weight = load[i] if i < len(load) and m.enabled else 0.0
                m.dq += h * (tau - weight - self.friction * m.dq) / self.inertia
                m.q += h * m.dq
                m.tau = tau


class PyBulletMotors:
    """The motors are a `SimArm`'s joints (and gripper): commands go to PyBullet, state comes from it."""

    def __init__(self, arm, config: RobotConfig) -> None:
        self.arm, self.config = arm, config
        self._last_width: float | None = None

    def advance(self, motors: list[SimMotor], dt: float) -> None:
        joints = motors[: len(self.config.joints)]
        state = self.arm.state()
        if all(m.enabled and m.command is not None for m in joints):
            q = np.array([_joint(m, m.command[0]) for m in joints])
            dq = np.array([m.config.direction * m.command[1] for m in joints])
            self.arm._send(q, dq)  # noqa: SLF001 - the motors below the safety layer, like real hardware
        else:
            self.arm._send(state.q, np.zeros_like(state.q))  # noqa: SLF001 - disabled motors hold (no sag)
        if self.config.gripper is not None:
            self._gripper(motors[-1], state.gripper_width_m)
        for _ in range(max(1, round(dt / self.arm.control_period_s))):
            self.arm.sync()  # physics steps
        self.read(motors)

    def read(self, motors: list[SimMotor]) -> None:
        state = self.arm.state()
        for i, m in enumerate(motors[: len(self.config.joints)]):
            c = m.config
            m.q, m.dq, m.tau = c.direction * (state.q[i] - c.zero_offset), c.direction * state.dq[i], \
                c.direction * float(state.tau[i])
        if self.config.gripper is not None:
            g, m = self.config.gripper, motors[-1]
            q_joint = g.q_closed + state.gripper_width_m / g.width_per_rad
            m.q, m.dq = g.direction * (q_joint - g.zero_offset), 0.0

    def _gripper(self, m: SimMotor, width_now: float) -> None:
        if not m.enabled or m.command is None:
            return
        g = self.config.gripper
        q_cmd, _, kp, _, _ = m.command
        width = max(0.0, (_joint(m, q_cmd) - g.q_closed) * g.width_per_rad)
        if self._last_width is None or abs(width - self._last_width) > 1e-3:
            force = max(20.0, kp * abs(width - width_now) / g.width_per_rad / g.nm_per_newton)
            self.arm.set_gripper(width, force)
            self._last_width = width


def _joint(m: SimMotor, q_motor: float) -> float:
    return m.config.direction * q_motor + m.config.zero_offset


_ON_CHANNEL: weakref.WeakValueDictionary[str, SimMotorBus] = weakref.WeakValueDictionary()


def motors_on(channel: str) -> SimMotorBus | None:
    """The simulated motors answering on virtual CAN `channel` (a sim-can arm's), if any: for fault injection."""
    return _ON_CHANNEL.get(channel)


class SimMotorBus:
    """The motors of `config` on their own python-can endpoint of `config.can` (interface and channel)."""

    def __init__(self, config: RobotConfig, backend: IntegratedMotors | PyBulletMotors | None = None,
                 q0: np.ndarray | None = None, seed: int = 0) -> None:
        self.config = config
        self.backend = backend or IntegratedMotors(gravity=GravityLoad(config) if config.gravity_compensation else None)
        self.motors = [SimMotor(m, m.default_limits) for m in config.motors]
        q0 = np.asarray(config.q_ready if q0 is None else q0, float)
        if config.gripper is not None:  # the gripper starts open
            q0 = np.append(q0, config.gripper.q_closed + config.gripper.max_width_m / config.gripper.width_per_rad)
        for m, q in zip(self.motors, q0, strict=True):
            m.q = m.config.direction * (q - m.config.zero_offset)
        if isinstance(self.backend, PyBulletMotors):
            self.backend.read(self.motors)
        self._by_id = {m.config.can_id: m for m in self.motors}
        self.fd = config.can.fd
        protocol = can.CanProtocol.CAN_FD if self.fd else can.CanProtocol.CAN_20
        self._bus = can.Bus(interface=config.can.interface, channel=config.can.channel, protocol=protocol)
        _ON_CHANNEL[config.can.channel] = self
        self._rng = np.random.default_rng(seed)
        self._delayed: list[tuple[float, can.Message]] = []
        self._scheduled: list[tuple[float, Callable[[], None]]] = []
        self._deferred: list[SimMotor] = []
        self._lockstep = True
        self._t = 0.0
        self._t_wall = time.perf_counter()
        self._lock = threading.RLock()  # re-entrant: a signal handler may disable motors from inside step()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.bus_dead = False

    def motor(self, name_or_id: str | int) -> SimMotor:
        """A motor by CAN id or joint name ("gripper" for the gripper)."""
        for m, c in zip(self.motors, self.config.motors, strict=True):
            name = getattr(c, "name", "gripper")
            if name_or_id in (c.can_id, name):
                return m
        raise KeyError(name_or_id)

    # --- running ---------------------------------------------------------------------------------------------

    def start(self) -> SimMotorBus:
        """Answer in a background thread on the wall clock (for a realtime CanArm)."""
        self._lockstep = False
        self._t_wall = time.perf_counter()
        self._thread = threading.Thread(target=self._run, name="sim-damiao-motors", daemon=True)
        self._thread.start()
        return self

    def poll(self) -> None:
        """Lockstep: handle every pending frame (MIT replies wait for `step`)."""
        with self._lock:
            while (msg := self._bus.recv(0.0)) is not None:
                self._handle(msg)
            self._flush_delayed()

    def step(self, dt: float) -> None:
        """Lockstep: handle pending frames, advance the motors by dt, reply to this cycle's MIT frames."""
        self.poll()
        with self._lock:
            self._t += dt
            self._run_scheduled()
            self._check_timeouts()
            self.backend.advance(self.motors, dt)
            deferred, self._deferred = self._deferred, []
            for m in deferred:
                self._reply_feedback(m)
            self._flush_delayed()

    def idle(self, dt: float) -> None:
        """Let `dt` seconds pass on the motors' clock with no frame handled: their communication timeouts run."""
        with self._lock:
            self._t += dt
            self._check_timeouts()

    def close(self) -> None:
        """Stop the thread, handle the frames still queued (the driver's last disables), release the endpoint, and
        let the motors' clock run on past their longest communication timeout: the driver has gone, nothing
        commands them any more (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._bus is not None:
            self.poll()
            self._bus.shutdown()
            self._bus = None
            self.idle(max(m.timeout_s for m in self.motors))

    def _check_timeouts(self) -> None:
        for m in self.motors:
            m.check_timeout(self._t)

    def _run(self) -> None:
        while not self._stop.is_set():
            msgs = [self._bus.recv(0.001)]
            while msgs[-1] is not None:
                msgs.append(self._bus.recv(0.0))
            with self._lock:
                now = time.perf_counter()
                dt, self._t_wall = now - self._t_wall, now
                self._t += dt
                self._run_scheduled()
                self._check_timeouts()
                self.backend.advance(self.motors, dt)
                for msg in msgs[:-1]:
                    self._handle(msg)
                deferred, self._deferred = self._deferred, []
                for m in deferred:
                    self._reply_feedback(m)
                self._flush_delayed()

    # --- faults ------------------------------------------------------------------------------------------------

    def schedule(self, at_s: float, action: Callable[[], None]) -> None:
        """Run `action` (a fault injection) once the motors' clock reaches `at_s`; at once if it has."""
        with self._lock:
            if at_s <= self._t:
                action()
            else:
                self._scheduled.append((at_s, action))

    def _run_scheduled(self) -> None:
        due = [action for t, action in self._scheduled if t <= self._t]
        self._scheduled = [(t, action) for t, action in self._scheduled if t > self._t]
        for action in due:
            action()

    def inject_bus_off(self) -> None:
        """The bus goes bus-off: one SocketCAN bus-off error frame, then no motor answers."""
        self.bus_dead = True
        self._bus.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, data=bytes(8),
                                   is_extended_id=False, is_fd=self.fd))

    def inject_error_passive(self) -> None:
        """A controller error-passive error frame (motors keep answering)."""
        self._bus.send(can.Message(arbitration_id=CAN_ERR_CRTL, is_error_frame=True,
                                   data=bytes([0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0]), is_extended_id=False,
                                   is_fd=self.fd))

    # --- protocol --------------------------------------------------------------------------------------------

    def _handle(self, msg: can.Message) -> None:
        if self.bus_dead or msg.is_error_frame or bool(msg.is_fd) != self.fd:
            return  # a frame of the other protocol is noise to this bus's motors
        data = bytes(msg.data)
        try:
            if msg.arbitration_id == PARAM_ID:
                self._param(data)
            elif (m := self._by_id.get(msg.arbitration_id)) is not None and not m.faults.silent:
                self._command(m, data)
        except FrameError:
            pass  # a real motor ignores frames it cannot parse

    def _command(self, m: SimMotor, data: bytes) -> None:
        m.last_command_s = self._t
        if is_special(data):
            kind = Special(data[7])
            if kind == Special.ENABLE:
                m.enabled = m.faults.status is None
                m.lost = False
            elif kind == Special.DISABLE:
                m.enabled, m.command = False, None
            elif kind == Special.SET_ZERO:
                m.q = 0.0
            elif kind == Special.CLEAR_ERROR:
                m.faults.status, m.lost = None, False
            self._reply_feedback(m)
            return
        command = unpack_mit(data, m.limits)
        m.mit_frames += 1
        if m.enabled and m.faults.status is None:
            m.command = command
        if m.faults.status is not None:
            m.enabled = False
        self._deferred.append(m)

    def _param(self, data: bytes) -> None:
        can_id, op, register = unpack_param_request(data)
        m = self._by_id.get(can_id)
        if m is None or m.faults.silent:
            return
        if op == REFRESH:
            self._reply_feedback(m)
            return
        if op == PARAM_WRITE and register == REG_TIMEOUT and not m.timeout_locked:
            m.timeout_steps = int(unpack_param_reply(data).value)
        values = {REG_PMAX: m.limits.p_max, REG_VMAX: m.limits.v_max, REG_TMAX: m.limits.t_max,
                  REG_MST_ID: m.config.master_id, REG_TIMEOUT: m.timeout_steps}
        if op in (PARAM_READ, PARAM_WRITE) and register in values:
            self._send(m, pack_param_reply(can_id, register, values[register], op))

    def _reply_feedback(self, m: SimMotor) -> None:
        if m.faults.silent:
            return
        temperature = 30 + int(abs(m.tau) / m.limits.t_max * 20)
        self._send(m, pack_feedback(m.config.can_id, m.status, m.q, m.dq, m.tau, temperature, temperature + 2,
                                    m.limits))

    def _send(self, m: SimMotor, data: bytes) -> None:
        m.replies += 1
        f = m.faults
        if (f.drop_every and m.replies % f.drop_every == 0) or (f.drop_rate and self._rng.random() < f.drop_rate):
            return
        msg = can.Message(arbitration_id=m.config.master_id, data=data, is_extended_id=False, is_fd=self.fd,
                          bitrate_switch=self.fd)
        if f.delay_s > 0:
            self._delayed.append((self._t + f.delay_s, msg))
        else:
            self._bus.send(msg)

    def _flush_delayed(self) -> None:
        due = [msg for t, msg in self._delayed if t <= self._t + 1e-12]
        self._delayed = [(t, msg) for t, msg in self._delayed if t > self._t + 1e-12]
        for msg in due:
            self._bus.send(msg)
