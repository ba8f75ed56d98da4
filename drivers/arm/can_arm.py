"""An arm of Damiao motors on one CAN bus (MIT mode), behind the `Arm` protocol.

Each control cycle sends one MIT command per motor (position, velocity feed-forward, the joint's gains) and
reads every motor's feedback. Two ways to run the cycles:
- realtime (hardware, simulated motors with their own thread): a background thread at `control_rate_hz` keeps
  sending the latest command (holding position when the planner sends none) and `sync()` waits for the next
  cycle; a watchdog disables the motors when a cycle starts `max_late_cycles` periods late. Connecting lowers
  the interpreter's GIL switch interval to 0.2 ms (process-wide) so other threads cannot hold the loop off;
- lockstep (simulation on the caller's clock): `sync()` runs one cycle, calling `on_cycle()` (one physics step)
  between sending and reading, so simulated time advances one period per cycle.

With `gravity_compensation` on, each command carries the gravity torque at the commanded joints (Pinocchio,
URDF inertias) as MIT feed-forward, so that low (compliant) gains do not let the arm sag.

Every fault (safety limit, status fault, stale feedback, late cycle, bus error) disables all motors and makes
the next `command()` / `sync()` raise ArmError naming the joint and the fault. SIGINT / SIGTERM disable the
motors too (installed at connect when running in the main thread).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from drivers.arm.base import Arm, ArmState
from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import (
    PARAM_ID,
    REG_MST_ID,
    REG_PMAX,
    REG_TMAX,
    REG_VMAX,
    Feedback,
    FrameError,
    MotorLimits,
    Special,
    Status,
    is_param_reply,
    pack_mit,
    param_read,
    refresh_request,
    special,
    unpack_feedback,
    unpack_param_reply,
)
from drivers.arm.kinematics import Kinematics
from drivers.arm.robot_config import GripperConfig, MotorConfig, RobotConfig
from drivers.arm.safety import SafetyGuard
from drivers.errors import ArmError, CanBusError

PMAX_MARGIN = 0.999  # commands stay inside the MIT range so they never read as special frames
MIN_GRIP_FORCE_N = 5.0
REQUEST_ATTEMPTS = 3  # connect-time requests are repeated this often before a motor counts as missing
GIL_SWITCH_INTERVAL_S = 2e-4  # Python's default 5 ms would let the planner thread delay a 2 ms control cycle


@dataclass
class MotorChannel:
    """One motor on the bus: its config, the limits read from it, and its latest feedback."""

    name: str
    config: MotorConfig
    limits: MotorLimits
    feedback: Feedback | None = None
    t_feedback: float = -np.inf
    malformed: int = 0

    def describe(self) -> str:
        return f"{self.name} (CAN id {self.config.can_id}, master 0x{self.config.master_id:X})"


@dataclass
class LoopStats:
    """Cycle start times (s, perf_counter) of the realtime loop, for rate and jitter."""

    starts: deque = field(default_factory=lambda: deque(maxlen=200_000))

    def summary(self, period_s: float) -> dict:
        t = np.asarray(self.starts)
        if len(t) < 3:
            return {"cycles": len(t)}
        periods = np.diff(t)
        jitter = np.abs(periods - period_s)
        return {"cycles": len(t), "loop_hz": float((len(t) - 1) / (t[-1] - t[0])),
                "period_ms_median": float(np.median(periods) * 1e3),
                "jitter_ms_median": float(np.median(jitter) * 1e3),
                "jitter_ms_p99": float(np.percentile(jitter, 99) * 1e3)}


class CanArm(Arm):
    """The arm of `config` on `bus`. Use as a context manager (connect: read limits, enable; leave: stop)."""

    def __init__(
        self,
        config: RobotConfig,
        bus: CanBus,
        kin: Kinematics | None = None,
        guard: SafetyGuard | None = None,
        realtime: bool = True,
        on_cycle: Callable[[], None] | None = None,
        on_close: Callable[[], None] | None = None,
    ) -> None:
        self.config = config
        self.bus = bus
        self.kin = kin or config.kinematics()
        self.limits = config.safety_limits(self.kin)
        self.guard = guard or SafetyGuard(self.limits, config.joint_names)
        self.control_period_s = config.control_period_s
        self.realtime = realtime
        self._on_cycle = on_cycle
        self._on_close = on_close
        self.joints = [MotorChannel(j.name, j, j.default_limits) for j in config.joints]
        self.gripper = (MotorChannel("gripper", config.gripper, config.gripper.default_limits)
                        if config.gripper else None)
        self.channels = [*self.joints, *([self.gripper] if self.gripper else [])]
        self._by_master = {c.config.master_id: c for c in self.channels}
        self._lock = threading.RLock()
        self._cycle_done = threading.Condition(self._lock)
        self._cycles = 0
        self._t0 = time.perf_counter()
        self._enabled = False
        self._closed = False
        self._fault: ArmError | None = None
        self._thread: threading.Thread | None = None
        self._stop_loop = threading.Event()
        self._old_handlers: dict[int, object] = {}
        self.stats = LoopStats()
        self._gravity_data = self.kin.model.createData()  # the loop thread's own Pinocchio workspace
        self._tau_max = np.array([j.tau_max for j in config.joints])
        n = len(self.joints)
        self._q_cmd, self._dq_cmd, self._fresh = np.zeros(n), np.zeros(n), False
        self._dq_prev_cmd: np.ndarray | None = None
        self._kp = np.array([j.kp for j in config.joints])
        self._kd = np.array([j.kd for j in config.joints])
        self._grip_width, self._grip_force = (config.gripper.max_width_m if config.gripper else 0.0), 40.0

    # --- Arm protocol ----------------------------------------------------------------------------------------

    @property
    def joint_names(self) -> list[str]:
        return self.config.joint_names

    def connect(self) -> None:
        """Read each motor's PMAX/VMAX/TMAX, check the config against them, enable, hold the measured position."""
        if self._enabled:
            return
        if self._closed:
            raise ArmError(f"arm {self.config.name!r} was disconnected: open a new one")
        self._fault = None
        try:
            for c in self.channels:
                c.limits = self._read_limits(c)
                self._check_motor_range(c)
            for c in self.channels:
                self._request_feedback(c, special(Special.ENABLE), c.config.can_id)
                if c.feedback.status != Status.ENABLED:
                    raise ArmError(f"motor {c.describe()} did not enable (status {c.feedback.status.name}): "
                                   "clear its error (`deploy arm enable --clear-errors`) and check its supply")
            self._check_start_position()
        except ArmError:
            self._disable_all()
            raise
        with self._lock:
            self._q_cmd, self._dq_cmd, self._fresh = self._measured_q(), np.zeros(len(self.joints)), False
            self._dq_prev_cmd = None
            if self.gripper is not None:
                self._grip_width = self._gripper_width()
            self._enabled = True
        self._install_signal_handlers()
        if self.realtime:
            sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_INTERVAL_S))
            self._stop_loop.clear()
            self._thread = threading.Thread(target=self._run, name=f"{self.config.name}-can-loop", daemon=True)
            self._thread.start()

    def probe(self) -> None:
        """Read each motor's limits and one feedback frame without enabling anything (state() then works)."""
        if self._closed:
            raise ArmError(f"arm {self.config.name!r} was disconnected: open a new one")
        for c in self.channels:
            c.limits = self._read_limits(c)
            self._request_feedback(c, refresh_request(c.config.can_id), PARAM_ID)

    def disconnect(self) -> None:
        """Stop (damp, disable), close the bus; safe after any failure."""
        self.stop()
        if not self._closed:
            self._closed = True
            self._restore_signal_handlers()
            self.bus.close()
            if self._on_close is not None:
                self._on_close()

    def state(self) -> ArmState:
        with self._lock:
            q, dq, tau = (np.array([self._to_joint(c, getattr(c.feedback, k, 0.0), k) for c in self.joints])
                          for k in ("q", "dq", "tau"))
            width = self._gripper_width() if self.gripper is not None else 0.0
            return ArmState(self._now(), q, dq, tau, width)

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
        if not self.realtime:
            self._cycle()
        else:
            with self._cycle_done:
                target = self._cycles + 1
                deadline = time.perf_counter() + 0.5 + 10 * self.control_period_s
                while self._cycles < target and self._fault is None and self._enabled:
                    if not self._cycle_done.wait(max(0.0, deadline - time.perf_counter())):
                        break
        self._raise_if_not_running()

    def set_gripper(self, width_m: float, force_n: float = 40.0) -> None:
        """Gripper opening target (clamped to [0, max width]); the motor pushes with about `force_n` at most."""
        if not np.isfinite(width_m) or not np.isfinite(force_n):
            raise ArmError(f"gripper command ({width_m}, {force_n} N) is not finite: a planner bug produced NaN")
        if self.gripper is None:
            return
        with self._lock:
            self._grip_width = float(np.clip(width_m, 0.0, self.config.gripper.max_width_m))
            self._grip_force = max(MIN_GRIP_FORCE_N, float(force_n))

    def stop(self) -> None:
        """Damp (kp = 0) for `stop_damping_s`, then disable every motor. Idempotent, never raises."""
        try:
            if self._enabled and self._fault is None:
                with self._lock:
                    self._kp = np.zeros(len(self.joints))
                    self._q_cmd, self._dq_cmd, self._fresh = self._measured_q(), np.zeros(len(self.joints)), True
                n = int(np.ceil(self.config.watchdog.stop_damping_s / self.control_period_s))
                for _ in range(n):
                    self.sync()
        except Exception:  # noqa: BLE001 - stopping must go on to disabling whatever happened
            pass
        self._shutdown_loop()
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
        """Per motor: name, ids, status, position/velocity/torque (joint side), temperatures, limits."""
        out = []
        with self._lock:
            for c in self.channels:
                fb = c.feedback
                out.append({
                    "name": c.name, "can_id": c.config.can_id, "master_id": c.config.master_id,
                    "motor": c.config.motor, "status": fb.status.name.lower() if fb else "no feedback",
                    "q": None if fb is None else self._to_joint(c, fb.q, "q"),
                    "dq": None if fb is None else self._to_joint(c, fb.dq, "dq"),
                    "tau": None if fb is None else self._to_joint(c, fb.tau, "tau"),
                    "t_mos_c": None if fb is None else fb.t_mos_c, "t_rotor_c": None if fb is None else fb.t_rotor_c,
                    "p_max": c.limits.p_max, "v_max": c.limits.v_max, "t_max": c.limits.t_max,
                })
        return out

    @property
    def fault(self) -> ArmError | None:
        return self._fault

    # --- the control cycle ---------------------------------------------------------------------------------

    def _run(self) -> None:
        period = self.control_period_s
        limit = self.config.watchdog.max_late_cycles * period
        next_t = time.perf_counter()
        while not self._stop_loop.is_set():
            late = time.perf_counter() - next_t
            if late > limit:
                self._trip(ArmError(
                    f"watchdog: control cycle started {late * 1e3:.1f} ms late (limit {limit * 1e3:.1f} ms, "
                    f"{self.config.control_rate_hz:.0f} Hz): motors disabled; the computer is overloaded: close "
                    "other programs, or lower control_rate_hz in the robot config"))
                return
            try:
                self._cycle()
            except ArmError as exc:
                self._trip(exc)
                return
            except Exception as exc:  # noqa: BLE001 - the loop must end safe on any bug
                self._trip(ArmError(f"control loop crashed ({type(exc).__name__}: {exc}): motors disabled; "
                                    "please report this bug"))
                return
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))

    def _cycle(self) -> None:
        """Send one MIT command per motor, read feedback, check faults. Raises ArmError (after disabling)."""
        if self.realtime:
            self.stats.starts.append(time.perf_counter())
        with self._lock:
            q, dq = self._q_cmd.copy(), (self._dq_cmd.copy() if self._fresh else np.zeros(len(self.joints)))
            self._fresh = False
            kp, kd = self._kp.copy(), self._kd.copy()
            tau = self._gravity(q)
            frames = [(c.config.can_id, self._mit_frame(c, q[i], dq[i], kp[i], kd[i], tau[i])) for i, c in
                      enumerate(self.joints)]
            if self.gripper is not None:
                frames.append((self.gripper.config.can_id, self._gripper_frame()))
        try:
            for can_id, data in frames:
                self.bus.send(can_id, data)
            if self._on_cycle is not None:
                self._on_cycle()
            self._collect_feedback()
        except ArmError as exc:
            self._trip(exc)
            raise
        with self._cycle_done:
            self._cycles += 1
            self._cycle_done.notify_all()

    def _collect_feedback(self) -> None:
        """Read feedback until every motor answered this cycle or half a period passed; check it."""
        start = self._now()
        pending = {c.config.master_id for c in self.channels}
        deadline = time.perf_counter() + (0.5 * self.control_period_s if self.realtime else 0.0)
        while pending:
            msg = self.bus.recv(max(0.0, deadline - time.perf_counter()))
            if msg is None:
                break
            c = self._by_master.get(msg.arbitration_id)
            if c is None:
                continue
            try:
                fb = unpack_feedback(bytes(msg.data), c.limits)
            except FrameError:
                c.malformed += 1  # a bad frame is ignored; a motor sending only bad frames goes stale below
                continue
            with self._lock:
                c.feedback, c.t_feedback = fb, self._now()
            pending.discard(c.config.master_id)
        self.bus.check_state()
        timeout = self.config.watchdog.feedback_timeout_s
        for i, c in enumerate(self.channels):
            age = start - c.t_feedback
            if age > timeout:
                raise ArmError(
                    f"watchdog: joint {c.describe()} sent no valid feedback for {age * 1e3:.0f} ms (limit "
                    f"{timeout * 1e3:.0f} ms, {c.malformed} malformed frames): motors disabled; check the motor's "
                    "power and CAN wiring, its master id, and the bus load")
            self._check_feedback(c, i)

    def _check_feedback(self, c: MotorChannel, i: int) -> None:
        fb = c.feedback
        if fb.status.is_fault:
            raise ArmError(f"joint {c.describe()} reports {fb.status.name.lower().replace('_', '-')}: motors "
                           f"disabled; {fb.status.fix}, then `deploy arm enable --clear-errors`")
        if fb.status == Status.DISABLED:
            raise ArmError(f"joint {c.describe()} disabled itself (its CAN timeout or a power dip): motors "
                           "disabled; check its supply and that its CAN timeout is longer than the control period")
        if c is not self.gripper:
            tau = abs(fb.tau)
            limit = self.config.joints[i].tau_max * self.config.watchdog.torque_margin
            if tau > limit:
                raise ArmError(f"safety stop: joint {c.describe()} torque {tau:.1f} N m exceeds {limit:.1f} N m "
                               "(tau_max x torque_margin): motors disabled; the arm hit something or is blocked: "
                               "clear the obstacle, or lower the motion limits")

    def _mit_frame(self, c: MotorChannel, q: float, dq: float, kp: float, kd: float, tau: float = 0.0) -> bytes:
        cfg = c.config
        q_m = cfg.direction * (q - cfg.zero_offset)
        lim = c.limits
        q_m = min(max(float(q_m), -PMAX_MARGIN * lim.p_max), PMAX_MARGIN * lim.p_max)
        return pack_mit(q_m, cfg.direction * float(dq), float(kp), float(kd), cfg.direction * float(tau), lim)

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """Joint torques (N m) holding the arm still against gravity at q (URDF inertias, Pinocchio RNEA)."""
        return pin.computeGeneralizedGravity(self.kin.model, self._gravity_data, np.asarray(q, float)).copy()

    def _gravity(self, q: np.ndarray) -> np.ndarray:
        """The feed-forward torque of this cycle: gravity compensation clipped to tau_max, or zeros."""
        if not self.config.gravity_compensation:
            return np.zeros(len(self.joints))
        return np.clip(self.gravity_torques(q), -self._tau_max, self._tau_max)

    def _gripper_frame(self) -> bytes:
        """Position command at the target width, kp lowered so that kp * (position error) stays within the
        torque of the requested force (`force * nm_per_newton`): the motor pushes with about that force."""
        g: GripperConfig = self.config.gripper
        q_target = g.q_closed + self._grip_width / g.width_per_rad
        fb = self.gripper.feedback
        error = 0.0 if fb is None else abs(q_target - self._to_joint(self.gripper, fb.q, "q"))
        kp = min(g.kp, self._grip_force * g.nm_per_newton / error) if error > 1e-9 else g.kp
        return self._mit_frame(self.gripper, q_target, 0.0, kp, g.kd)

    # --- connect-time requests -----------------------------------------------------------------------------

    def _read_limits(self, c: MotorChannel) -> MotorLimits:
        values = []
        for register in (REG_PMAX, REG_VMAX, REG_TMAX):
            values.append(read_param(self.bus, c.config.can_id, c.config.master_id, register,
                                     self.config.watchdog.reply_timeout_s, c.describe()))
        try:
            return MotorLimits(*values)
        except ValueError as exc:
            raise ArmError(f"motor {c.describe()} reports invalid limits {values}: {exc}; check its firmware "
                           "settings with the Damiao tool") from exc

    def _check_motor_range(self, c: MotorChannel) -> None:
        if c is self.gripper:
            return
        i = self.joints.index(c)
        j = self.config.joints[i]
        motor_q = np.abs(j.direction * (np.array([self.limits.q_min[i], self.limits.q_max[i]]) - j.zero_offset))
        if motor_q.max() >= PMAX_MARGIN * c.limits.p_max:
            raise ArmError(f"joint {c.describe()}: its range needs motor positions up to {motor_q.max():.2f} rad "
                           f"but the motor's PMAX is {c.limits.p_max:.2f}: narrow q_min/q_max or fix zero_offset")
        if self.limits.v_max[i] > c.limits.v_max:
            raise ArmError(f"joint {c.describe()}: velocity limit {self.limits.v_max[i]:.2f} rad/s exceeds the "
                           f"motor's VMAX {c.limits.v_max:.2f}: lower v_max in the robot config")
        if j.tau_max > c.limits.t_max:
            raise ArmError(f"joint {c.describe()}: tau_max {j.tau_max:.1f} N m exceeds the motor's TMAX "
                           f"{c.limits.t_max:.1f}: lower tau_max in the robot config")

    def _check_start_position(self) -> None:
        q = self._measured_q()
        tol = 0.05
        for i, c in enumerate(self.joints):
            if not self.limits.q_min[i] - tol <= q[i] <= self.limits.q_max[i] + tol:
                raise ArmError(
                    f"joint {c.describe()} reads {q[i]:.3f} rad, outside its limits [{self.limits.q_min[i]:.3f}, "
                    f"{self.limits.q_max[i]:.3f}]: motors disabled; check direction and zero_offset in the robot "
                    "config, or set the zero at a known pose (`deploy arm zero`)")

    def _request_feedback(self, c: MotorChannel, data: bytes, arbitration_id: int) -> None:
        """Send a frame the motor answers with feedback and wait for it (REQUEST_ATTEMPTS x reply_timeout_s)."""
        timeout = self.config.watchdog.reply_timeout_s
        for _ in range(REQUEST_ATTEMPTS):
            self.bus.send(arbitration_id, data)
            deadline = time.perf_counter() + timeout
            while (remaining := deadline - time.perf_counter()) > 0:
                msg = self.bus.recv(remaining)
                if msg is None:
                    break
                if msg.arbitration_id != c.config.master_id or is_param_reply(bytes(msg.data), c.config.can_id):
                    continue
                try:
                    c.feedback, c.t_feedback = unpack_feedback(bytes(msg.data), c.limits), self._now()
                    return
                except FrameError:
                    c.malformed += 1
        raise ArmError(f"motor {c.describe()} did not answer {REQUEST_ATTEMPTS} times within {timeout * 1e3:.0f} ms: "
                       "check its power, CAN id, master id and the bus bitrate (`deploy arm scan`)")

    # --- helpers -------------------------------------------------------------------------------------------

    def _now(self) -> float:
        return time.perf_counter() - self._t0 if self.realtime else self._cycles * self.control_period_s

    def _to_joint(self, c: MotorChannel, value: float, kind: str) -> float:
        return c.config.direction * value + (c.config.zero_offset if kind == "q" else 0.0)

    def _measured_q(self) -> np.ndarray:
        return np.array([self._to_joint(c, c.feedback.q if c.feedback else 0.0, "q") for c in self.joints])

    def _gripper_width(self) -> float:
        fb = self.gripper.feedback
        if fb is None:
            return 0.0
        g = self.config.gripper
        return float(max(0.0, (self._to_joint(self.gripper, fb.q, "q") - g.q_closed) * g.width_per_rad))

    def _raise_if_not_running(self) -> None:
        if self._fault is not None:
            raise self._fault
        if not self._enabled:
            raise ArmError(f"arm {self.config.name!r} is not enabled (stopped or never connected): connect() first")

    def _trip(self, exc: ArmError) -> None:
        """Record the first fault, disable every motor, end the loop."""
        with self._cycle_done:
            if self._fault is None:
                self._fault = exc
            self._cycle_done.notify_all()
        self._stop_loop.set()
        self._disable_all()

    def _disable_all(self) -> None:
        for c in self.channels:
            for _ in range(2):  # twice: one lost frame must not leave a motor enabled
                try:
                    self.bus.send(c.config.can_id, special(Special.DISABLE))
                except (CanBusError, ArmError):
                    pass
        self.bus.flush()

    def _shutdown_loop(self) -> None:
        self._stop_loop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
        self._thread = None

    def _install_signal_handlers(self) -> None:
        if threading.current_thread() is not threading.main_thread() or self._old_handlers:
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old_handlers[sig] = signal.signal(sig, self._on_signal)

    def _restore_signal_handlers(self) -> None:
        for sig, handler in self._old_handlers.items():
            signal.signal(sig, handler)
        self._old_handlers.clear()

    def _on_signal(self, signum: int, _frame) -> None:
        self._trip(ArmError(f"stopped by {signal.Signals(signum).name}: motors disabled"))
        self._shutdown_loop()
        self._enabled = False
        self._restore_signal_handlers()
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)


def read_param(bus: CanBus, can_id: int, master_id: int | None, register: int, timeout_s: float,
               who: str, attempts: int = REQUEST_ATTEMPTS) -> float:
    """Read one parameter register of motor `can_id` (answer on `master_id`, any id if None); `attempts`
    requests of `timeout_s` each, so that one lost frame does not fail a connect."""
    for _ in range(attempts):
        bus.send(PARAM_ID, param_read(can_id, register))
        deadline = time.perf_counter() + timeout_s
        while (remaining := deadline - time.perf_counter()) > 0:
            msg = bus.recv(remaining)
            if msg is None:
                break
            data = bytes(msg.data)
            if (master_id is None or msg.arbitration_id == master_id) and is_param_reply(data, can_id):
                reply = unpack_param_reply(data)
                if reply.register == register:
                    return reply.value
    raise ArmError(f"motor {who} did not answer a parameter read (register {register}) {attempts} times within "
                   f"{timeout_s * 1e3:.0f} ms: check its power, CAN id, master id and the bus bitrate "
                   "(`deploy arm scan` lists the ids that answer)")


@dataclass(frozen=True)
class ScannedMotor:
    """A motor that answered a scan: its ids, status and the limits its registers hold."""

    can_id: int
    master_id: int
    status: str
    limits: MotorLimits

    def to_dict(self) -> dict:
        return {"can_id": self.can_id, "master_id": self.master_id, "status": self.status,
                "p_max": self.limits.p_max, "v_max": self.limits.v_max, "t_max": self.limits.t_max}


def scan_bus(bus: CanBus, ids: range, timeout_s: float = 0.02) -> list[ScannedMotor]:
    """Which CAN ids answer: each id's master id (register 7), PMAX/VMAX/TMAX and status (one feedback frame,
    requested without changing the motor's state). Ids that do not answer are skipped."""
    found = []
    for can_id in ids:
        try:
            master = int(read_param(bus, can_id, None, REG_MST_ID, timeout_s, f"CAN id {can_id}"))
        except ArmError:
            continue
        values = [read_param(bus, can_id, master, r, timeout_s, f"CAN id {can_id}") for r in
                  (REG_PMAX, REG_VMAX, REG_TMAX)]
        limits = MotorLimits(*values)
        bus.send(PARAM_ID, refresh_request(can_id))
        status = "no feedback"
        deadline = time.perf_counter() + timeout_s
        while (remaining := deadline - time.perf_counter()) > 0:
            msg = bus.recv(remaining)
            if msg is None:
                break
            if msg.arbitration_id == master and not is_param_reply(bytes(msg.data), can_id):
                try:
                    status = unpack_feedback(bytes(msg.data), limits).status.name.lower()
                except FrameError:
                    status = "malformed feedback"
                break
        found.append(ScannedMotor(can_id, master, status, limits))
    return found
