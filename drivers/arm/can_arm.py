"""An arm of Damiao motors on one CAN bus (MIT mode), behind the `Arm` protocol.

Each control cycle sends one MIT command per motor (position, velocity feed-forward, the joint's gains) and
reads every motor's feedback. The cycles run in a `ControlLoop` (drivers/arm/control_loop.py):
- realtime (hardware, simulated motors with their own thread): a background thread at `control_rate_hz` keeps
  sending the latest command (holding position when the planner sends none) and `sync()` waits for the next
  cycle; a watchdog disables the motors when a cycle starts `max_late_cycles` periods late;
- lockstep (simulation on the caller's clock): `sync()` runs one cycle, calling `on_cycle()` (one physics step)
  between sending and reading, so simulated time advances one period per cycle.

With `gravity_compensation` on, each command carries the gravity torque at the commanded joints (Pinocchio,
URDF inertias) as MIT feed-forward, so that low (compliant) gains do not let the arm sag.

Every fault (safety limit, status fault, stale feedback, late cycle, bus error) disables all motors and makes
the next `command()` / `sync()` raise ArmError naming the joint and the fault, and any motor that did not confirm
the disable (drivers/arm/disable.py). SIGINT / SIGTERM disable the motors too (installed at connect when running
in the main thread, unless drivers.interrupts turns them into an exception that stops the arm on its way out;
then stopping, disabling, reporting and closing the bus complete before a signal that came meanwhile is raised).
An exception leaving `with arm:` carries the motors' final states as `motors`. The motors' channels, requests and
the bus scan live in drivers/arm/motor_channels.py (re-exported here).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from drivers.arm.base import GRIP_FORCE_N, Arm, ArmState
from drivers.arm.can_bus import CanBus
from drivers.arm.control_loop import ControlLoop, LoopStats
from drivers.arm.damiao import PARAM_ID, Special, Status, refresh_request, special
from drivers.arm.disable import disable_and_confirm, motor_states, wait_for_timeouts, with_summary
from drivers.arm.kinematics import Kinematics
from drivers.arm.motor_channels import (
    PMAX_MARGIN,
    MotorChannel,
    ScannedMotor,
    check_feedback,
    gripper_frame,
    gripper_width,
    read_limits,
    read_param,
    receive_feedback,
    request_feedback,
    scan_bus,
    set_timeout,
)
from drivers.arm.robot_config import RobotConfig, WatchdogConfig
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.arm.signals import StopSignals
from drivers.errors import ArmError
from drivers.interrupts import Interrupted, critical
from drivers.interrupts import active as interrupts_active

__all__ = ["CanArm", "LoopStats", "MotorChannel", "ScannedMotor", "read_param", "scan_bus"]

MIN_GRIP_FORCE_N = 5.0
START_TOLERANCE_RAD = 0.05  # how far outside its limits a joint may read at connect


class CanArm(Arm):
    """The arm of `config` on `bus`. Use as a context manager (connect: read limits, enable; leave: stop)."""

    def __init__(self, config: RobotConfig, bus: CanBus, kin: Kinematics | None = None,
                 guard: SafetyGuard | None = None, realtime: bool = True,
                 on_cycle: Callable[[], None] | None = None, on_close: Callable[[], None] | None = None) -> None:
        self.config, self.bus = config, bus
        self.kin = kin or config.kinematics()
        self.guard = guard or config.safety_guard(self.kin)
        self.control_period_s = config.control_period_s
        self.realtime = realtime
        self._on_close = on_close
        self.joints = [MotorChannel(j.name, j, j.default_limits) for j in config.joints]
        self.gripper = (MotorChannel("gripper", config.gripper, config.gripper.default_limits)
                        if config.gripper else None)
        self.channels = [*self.joints, *([self.gripper] if self.gripper else [])]
        self._by_master = {c.config.master_id: c for c in self.channels}
        self.loop = ControlLoop(config.name, config.control_rate_hz, config.watchdog.max_late_cycles, realtime,
                                send=self._send_commands, read=self._read_feedback, on_trip=self._on_trip,
                                on_cycle=on_cycle)
        self.stats: LoopStats = self.loop.stats
        self._lock = self.loop.lock
        self._signals = StopSignals(self._stopped_by)
        self._enabled, self._closed = False, False
        self._unconfirmed, self._timed_out, self._last_sent_s = set(), set(), -np.inf  # see _disable_all
        self._gravity_data = self.kin.model.createData()  # the loop thread's own Pinocchio workspace
        self._tau_max = np.array([j.tau_max for j in config.joints])
        n = len(self.joints)
        self._q_cmd, self._dq_cmd, self._fresh = np.zeros(n), np.zeros(n), False
        self._dq_prev_cmd: np.ndarray | None = None
        self._kp = np.array([j.kp for j in config.joints])
        self._kd = np.array([j.kd for j in config.joints])
        self._grip_width = config.gripper.max_width_m if config.gripper else 0.0
        self._grip_force = config.grip_force_n

    # --- Arm protocol ----------------------------------------------------------------------------------------

    @property
    def joint_names(self) -> list[str]:
        return self.config.joint_names

    @property
    def bus_channel(self) -> str:
        return self.config.can.channel

    def connect(self) -> None:
        """Read each motor's PMAX/VMAX/TMAX, check the config against them, enable, hold the measured position."""
        if self._enabled:
            return
        if self._closed:
            raise ArmError(f"arm {self.config.name!r} was disconnected: open a new one")
        self.loop.clear_fault()
        try:
            self._last_sent_s = enable_motors(self.bus, self.channels, self.limits, self.config.watchdog, self.loop.now)
            check_start_position(self.joints, self._measured_q(), self.limits)
        except ArmError:
            self._disable_all()
            raise
        with self._lock:
            self._q_cmd, self._dq_cmd, self._fresh = self._measured_q(), np.zeros(len(self.joints)), False
            self._dq_prev_cmd = None
            if self.gripper is not None:
                self._grip_width = gripper_width(self.gripper, self.config.gripper)
            self._enabled = True
        if not interrupts_active():
            self._signals.install()
        self.loop.start()

    def probe(self) -> None:
        """Read each motor's limits and one feedback frame without enabling anything (state() then works)."""
        if self._closed:
            raise ArmError(f"arm {self.config.name!r} was disconnected: open a new one")
        timeout = self.config.watchdog.reply_timeout_s
        for c in self.channels:
            c.limits = read_limits(self.bus, c, timeout)
            request_feedback(self.bus, c, refresh_request(c.config.can_id), PARAM_ID, timeout, self.loop.now)

    def disconnect(self) -> None:
        """Stop (damp, disable), close the bus; safe after any failure. Signals wait for its end."""
        with critical:
            self.stop()
            if not self._closed:
                self._closed = True
                self._signals.restore()
                self.bus.close()
                if self._on_close is not None:
                    self._on_close()

    def state(self) -> ArmState:
        with self._lock:
            q, dq, tau = (np.array([c.to_joint(getattr(c.feedback, k, 0.0), k) for c in self.joints])
                          for k in ("q", "dq", "tau"))
            width = gripper_width(self.gripper, self.config.gripper) if self.gripper is not None else 0.0
            return ArmState(self.loop.now(), q, dq, tau, width)

    def command(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        self._raise_if_not_running()
        q = np.asarray(q, float)
        try:
            tool = self.kin.fk(q)[:3, 3] if q.shape == (len(self.joints),) else np.full(3, np.nan)
            self.guard.check(q, dq, self._q_cmd, self.control_period_s, tool, self._dq_prev_cmd, self.state().q)
        except ArmError:
            self.stop()
            raise
        with self._lock:
            self._q_cmd = q.copy()
            self._dq_cmd = np.zeros(len(q)) if dq is None else np.asarray(dq, float).copy()
            self._dq_prev_cmd = None if dq is None else self._dq_cmd.copy()
            self._fresh = True

    def sync(self) -> None:
        self._raise_if_not_running()
        self.loop.sync(lambda: self._enabled)
        self._raise_if_not_running()

    def set_gripper(self, width_m: float, force_n: float = GRIP_FORCE_N) -> None:
        """Gripper opening target (clamped to [0, max width]); the motor pushes with about `force_n` at most."""
        if not np.isfinite(width_m) or not np.isfinite(force_n):
            raise ArmError(f"gripper command ({width_m}, {force_n} N) is not finite: a planner bug produced NaN")
        if self.gripper is None:
            return
        with self._lock:
            self._grip_width = float(np.clip(width_m, 0.0, self.config.gripper.max_width_m))
            self._grip_force = max(MIN_GRIP_FORCE_N, float(force_n))

    def stop(self) -> None:
        """Damp (kp = 0) for `stop_damping_s`, then disable every motor. Idempotent, raises no Exception; nothing
        to do once disconnected. Signals (drivers.interrupts) wait for its end: a second Ctrl-C cannot cut it."""
        if self._closed:
            return
        with critical:
            try:
                if self._enabled and self.loop.fault is None:
                    with self._lock:
                        self._kp = np.zeros(len(self.joints))
                        self._q_cmd, self._dq_cmd, self._fresh = self._measured_q(), np.zeros(len(self.joints)), True
                    for _ in range(int(np.ceil(self.config.watchdog.stop_damping_s / self.control_period_s))):
                        self.sync()
            except Exception:  # noqa: BLE001 - stopping must go on to disabling whatever happened
                pass
            finally:
                self.loop.stop()
                self._disable_all()
                with self._lock:
                    self._enabled = False
                    self._kp = np.array([j.kp for j in self.config.joints])

    # --- extras --------------------------------------------------------------------------------------------

    def set_compliance(self, compliant: bool) -> None:
        """Switch every joint to its compliant gains (kp_compliant, kd_compliant), e.g. while pulling a handle."""
        with self._lock:
            self._kp = np.array([j.kp_compliant if compliant else j.kp for j in self.config.joints])
            self._kd = np.array([j.kd_compliant if compliant else j.kd for j in self.config.joints])

    def clear_errors(self) -> None:
        """Send clear-error to every motor (before enabling a motor that reported a fault)."""
        for c in self.channels:
            self.bus.send(c.config.can_id, special(Special.CLEAR_ERROR))

    def motor_report(self) -> list[dict]:
        """Per motor: name, ids, status, joint-side q / dq / tau, temperatures, limits, communication timeout."""
        with self._lock:
            return [c.report() for c in self.channels]

    def motor_states(self) -> list[dict]:
        """Every motor's state (drivers/arm/disable.py `motor_states`)."""
        with self._lock:
            return motor_states(self.channels, self._unconfirmed, self._timed_out)

    def __enter__(self) -> CanArm:
        """Connect; a failed connect leaves as `__exit__` does (`with` calls none after a failed enter)."""
        try:
            self.connect()
        except BaseException as exc:
            self.__exit__(type(exc), exc, None)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        disconnect_reporting(self, exc)

    fault = property(lambda self: self.loop.fault, doc="The fault that tripped the loop (None while running).")

    # --- the control cycle (called by the loop) --------------------------------------------------------------

    def _send_commands(self) -> None:
        """One MIT command per motor: the latest command (its velocity only in the cycle after it came), the
        current gains, gravity feed-forward; the gripper's force-limited position command."""
        with self._lock:
            q, dq = self._q_cmd.copy(), (self._dq_cmd.copy() if self._fresh else np.zeros(len(self.joints)))
            self._fresh = False
            kp, kd = self._kp.copy(), self._kd.copy()
            tau = self._gravity(q)
            frames = [(c.config.can_id, c.mit_frame(q[i], dq[i], kp[i], kd[i], tau[i])) for i, c in
                      enumerate(self.joints)]
            if self.gripper is not None:
                frames.append((self.gripper.config.can_id, gripper_frame(
                    self.gripper, self.config.gripper, self._grip_width, self._grip_force)))
        for can_id, data in frames:
            self.bus.send(can_id, data)
        self._last_sent_s = time.perf_counter()

    def _read_feedback(self) -> None:
        """Read feedback until every motor answered this cycle or half a period passed; check it."""
        start = self.loop.now()
        wait_s = 0.5 * self.control_period_s if self.realtime else 0.0
        receive_feedback(self.bus, self._by_master, self._lock, self.loop.now, wait_s)
        self.bus.check_state()
        for i, c in enumerate(self.channels):
            tau_max = None if c is self.gripper else self.config.joints[i].tau_max
            check_feedback(c, start - c.t_feedback, self.config.watchdog, tau_max)

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """Joint torques (N m) holding the arm still against gravity at q (URDF inertias, Pinocchio RNEA)."""
        return pin.computeGeneralizedGravity(self.kin.model, self._gravity_data, np.asarray(q, float)).copy()

    def _gravity(self, q: np.ndarray) -> np.ndarray:
        """The feed-forward torque of this cycle: gravity compensation clipped to tau_max, or zeros."""
        if not self.config.gravity_compensation:
            return np.zeros(len(self.joints))
        return np.clip(self.gravity_torques(q), -self._tau_max, self._tau_max)

    def _measured_q(self) -> np.ndarray:
        return np.array([c.to_joint(c.feedback.q if c.feedback else 0.0, "q") for c in self.joints])

    def _raise_if_not_running(self) -> None:
        if self.loop.fault is not None:
            raise self.loop.fault
        if not self._enabled:
            raise ArmError(f"arm {self.config.name!r} is not enabled (stopped or never connected): connect() first")

    def _disable_all(self) -> None:
        """Disable every motor; the unconfirmed ones' communication timeouts are waited out (drivers/arm/disable.py)."""
        unconfirmed = disable_and_confirm(self.bus, self.channels, self.config.watchdog.reply_timeout_s, self._lock,
                                          self.loop.now)
        self._unconfirmed = {c.name for c in unconfirmed}
        self._timed_out = {c.name for c in wait_for_timeouts(unconfirmed, self._last_sent_s)}

    def _on_trip(self, fault: ArmError) -> ArmError:
        """The loop tripped: disable every motor; the fault's message then names any that did not confirm."""
        self._disable_all()
        message = with_summary(str(fault), self.motor_states())
        return fault if message == str(fault) else type(fault)(message)

    def _stopped_by(self, signal_name: str) -> None:
        """SIGINT / SIGTERM: trip (motors disabled), end the loop; the handler then raises."""
        self.loop.trip(ArmError(f"stopped by {signal_name}: motors disabled"))
        self.loop.stop()
        self._enabled = False


def disconnect_reporting(arm: CanArm, exc: BaseException | None) -> None:
    """Disconnect `arm`; the leaving exception `exc` carries the motors' final states as `motors`, and so does the
    Interrupted of a signal that came meanwhile (raised once all is done: drivers/interrupts.py)."""
    try:
        with critical:
            arm.disconnect()
            if exc is not None:
                exc.motors = arm.motor_states()
    except Interrupted as late:
        late.motors = arm.motor_states()
        raise


def enable_motors(bus: CanBus, channels: list[MotorChannel], limits: SafetyLimits, watchdog: WatchdogConfig,
                  now: Callable[[], float]) -> float:
    """Read each motor's PMAX/VMAX/TMAX, check the joints' ranges against them (`channels`: the joints in order,
    then the gripper), set and read back each motor's communication timeout (`watchdog.motor_timeout_s`), enable
    each motor; ArmError naming the motor and the fix otherwise. Returns the time (perf_counter) of the last enable.
    """
    timeout_s = watchdog.reply_timeout_s
    for i, c in enumerate(channels):
        c.limits = read_limits(bus, c, timeout_s)
        if i < len(limits.q_min):
            check_motor_range(c, limits, i)
        set_timeout(bus, c, watchdog.motor_timeout_s, timeout_s)
    for c in channels:
        request_feedback(bus, c, special(Special.ENABLE), c.config.can_id, timeout_s, now)
        if c.feedback.status != Status.ENABLED:
            raise ArmError(f"motor {c.describe()} did not enable (status {c.feedback.status.name}): "
                           "clear its error (`deploy arm enable --clear-errors`) and check its supply")
    return time.perf_counter()


def check_motor_range(c: MotorChannel, limits: SafetyLimits, i: int) -> None:
    """ArmError if joint `i`'s position range, velocity or torque limit exceeds what its motor's PMAX / VMAX /
    TMAX registers allow."""
    j = c.config
    motor_q = np.abs(j.direction * (np.array([limits.q_min[i], limits.q_max[i]]) - j.zero_offset))
    if motor_q.max() >= PMAX_MARGIN * c.limits.p_max:
        raise ArmError(f"joint {c.describe()}: its range needs motor positions up to {motor_q.max():.2f} rad "
                       f"but the motor's PMAX is {c.limits.p_max:.2f}: narrow q_min/q_max or fix zero_offset")
    if limits.v_max[i] > c.limits.v_max:
        raise ArmError(f"joint {c.describe()}: velocity limit {limits.v_max[i]:.2f} rad/s exceeds the "
                       f"motor's VMAX {c.limits.v_max:.2f}: lower v_max in the robot config")
    if j.tau_max > c.limits.t_max:
        raise ArmError(f"joint {c.describe()}: tau_max {j.tau_max:.1f} N m exceeds the motor's TMAX "
                       f"{c.limits.t_max:.1f}: lower tau_max in the robot config")


def check_start_position(joints: list[MotorChannel], q: np.ndarray, limits: SafetyLimits) -> None:
    """ArmError if a joint reads outside its limits (beyond START_TOLERANCE_RAD) at connect."""
    tol = START_TOLERANCE_RAD
    for i, c in enumerate(joints):
        if not limits.q_min[i] - tol <= q[i] <= limits.q_max[i] + tol:
            raise ArmError(
                f"joint {c.describe()} reads {q[i]:.3f} rad, outside its limits [{limits.q_min[i]:.3f}, "
                f"{limits.q_max[i]:.3f}]: motors disabled; check direction and zero_offset in the robot "
                "config, or set the zero at a known pose (`deploy arm zero`)")
