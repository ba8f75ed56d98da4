"""The arm's Damiao motors on one CAN bus: channels, request/reply, the per-cycle feedback read, the bus scan.

A `MotorChannel` converts between the joint side (the robot config's joint, `direction` and `zero_offset`
applied) and the motor side (what the frames carry). `request_reply` is the one send-and-wait loop under
parameter reads, connect-time feedback requests and the scan; `receive_feedback` reads one cycle's feedback.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import can
import numpy as np

from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import (
    PARAM_ID,
    REG_MST_ID,
    REG_PMAX,
    REG_TIMEOUT,
    REG_TMAX,
    REG_VMAX,
    TIMEOUT_UNIT_S,
    Feedback,
    FrameError,
    MotorLimits,
    Status,
    is_param_reply,
    pack_mit,
    param_read,
    param_write,
    refresh_request,
    timeout_steps,
    unpack_feedback,
    unpack_param_reply,
)
from drivers.arm.robot_config import GripperConfig, MotorConfig, WatchdogConfig
from drivers.errors import ArmError

PMAX_MARGIN = 0.999  # commands stay inside the MIT range so they never read as special frames
REQUEST_ATTEMPTS = 3  # connect-time requests are repeated this often before a motor counts as missing

T = TypeVar("T")


@dataclass
class MotorChannel:
    """One motor on the bus: its config, the limits read from it, the communication timeout it holds (s, read back
    after setting it; None before), and its latest feedback."""

    name: str
    config: MotorConfig
    limits: MotorLimits
    timeout_s: float | None = None
    feedback: Feedback | None = None
    t_feedback: float = -np.inf
    malformed: int = 0

    def describe(self) -> str:
        return f"{self.name} (CAN id {self.config.can_id}, master 0x{self.config.master_id:X})"

    def to_joint(self, value: float, kind: str = "q") -> float:
        """A motor-side position (`kind` "q"), velocity ("dq") or torque ("tau") on the joint side."""
        return self.config.direction * value + (self.config.zero_offset if kind == "q" else 0.0)

    def mit_frame(self, q: float, dq: float, kp: float, kd: float, tau: float = 0.0) -> bytes:
        """MIT command for joint-side q, dq, tau; the motor position is clamped inside PMAX. ArmError for a
        non-finite value: such a command is never encoded, let alone sent."""
        if not all(math.isfinite(v) for v in (q, dq, kp, kd, tau)):
            raise ArmError(f"motor {self.describe()}: MIT command (q {q}, dq {dq}, kp {kp}, kd {kd}, tau {tau}) is not "
                           "finite: refused; a controller bug produced NaN or inf")
        cfg = self.config
        q_m = cfg.direction * (q - cfg.zero_offset)
        lim = self.limits
        q_m = min(max(float(q_m), -PMAX_MARGIN * lim.p_max), PMAX_MARGIN * lim.p_max)
        return pack_mit(q_m, cfg.direction * float(dq), float(kp), float(kd), cfg.direction * float(tau), lim)

    def decode(self, data: bytes) -> Feedback | None:
        """A feedback payload decoded with this motor's limits; None (counted in `malformed`) if it is bad."""
        try:
            return unpack_feedback(data, self.limits)
        except FrameError:
            self.malformed += 1
            return None

    def report(self) -> dict:
        """Name, ids, status, joint-side q / dq / tau, temperatures and limits (None where no feedback came)."""
        fb = self.feedback
        return {
            "name": self.name, "can_id": self.config.can_id, "master_id": self.config.master_id,
            "motor": self.config.motor, "status": fb.status.name.lower() if fb else "no feedback",
            "q": None if fb is None else self.to_joint(fb.q, "q"),
            "dq": None if fb is None else self.to_joint(fb.dq, "dq"),
            "tau": None if fb is None else self.to_joint(fb.tau, "tau"),
            "t_mos_c": None if fb is None else fb.t_mos_c, "t_rotor_c": None if fb is None else fb.t_rotor_c,
            "p_max": self.limits.p_max, "v_max": self.limits.v_max, "t_max": self.limits.t_max,
            "timeout_ms": None if self.timeout_s is None else round(self.timeout_s * 1e3, 1),
        }


def gripper_width(c: MotorChannel, g: GripperConfig) -> float:
    """The gripper opening (m) its motor's latest feedback reads, 0 before any feedback."""
    fb = c.feedback
    if fb is None:
        return 0.0
    return float(max(0.0, (c.to_joint(fb.q, "q") - g.q_closed) * g.width_per_rad))


def gripper_frame(c: MotorChannel, g: GripperConfig, width_m: float, force_n: float) -> bytes:
    """Position command at `width_m`, kp lowered so that kp * (position error) stays within the torque of
    `force_n` (`force * nm_per_newton`): the motor pushes with about that force."""
    q_target = g.q_closed + width_m / g.width_per_rad
    fb = c.feedback
    error = 0.0 if fb is None else abs(q_target - c.to_joint(fb.q, "q"))
    kp = min(g.kp, force_n * g.nm_per_newton / error) if error > 1e-9 else g.kp
    return c.mit_frame(q_target, 0.0, kp, g.kd)


def request_reply(bus: CanBus, arbitration_id: int, data: bytes, reply: Callable[[can.Message], T | None],
                  timeout_s: float, attempts: int = REQUEST_ATTEMPTS) -> T | None:
    """Send `data` and wait up to `timeout_s` for the first frame `reply` turns into a value (None: not the
    answer, keep waiting); `attempts` sends in all. None if no frame was accepted."""
    for _ in range(attempts):
        bus.send(arbitration_id, data)
        deadline = time.perf_counter() + timeout_s
        while (remaining := deadline - time.perf_counter()) > 0:
            msg = bus.recv(remaining)
            if msg is None:
                break
            value = reply(msg)
            if value is not None:
                return value
    return None


def read_param(bus: CanBus, can_id: int, master_id: int | None, register: int, timeout_s: float,
               who: str, attempts: int = REQUEST_ATTEMPTS) -> float:
    """Read one parameter register of motor `can_id` (answer on `master_id`, any id if None); `attempts`
    requests of `timeout_s` each, so that one lost frame does not fail a connect."""

    def reply(msg: can.Message) -> float | None:
        data = bytes(msg.data)
        if (master_id is None or msg.arbitration_id == master_id) and is_param_reply(data, can_id):
            answer = unpack_param_reply(data)
            if answer.register == register:
                return answer.value
        return None

    value = request_reply(bus, PARAM_ID, param_read(can_id, register), reply, timeout_s, attempts)
    if value is None:
        raise ArmError(f"motor {who} did not answer a parameter read (register {register}) {attempts} times within "
                       f"{timeout_s * 1e3:.0f} ms: check its power, CAN id, master id and the bus bitrate "
                       "(`deploy arm scan` lists the ids that answer)")
    return value


def read_limits(bus: CanBus, c: MotorChannel, timeout_s: float) -> MotorLimits:
    """The PMAX / VMAX / TMAX registers of channel `c`'s motor."""
    values = []
    for register in (REG_PMAX, REG_VMAX, REG_TMAX):
        values.append(read_param(bus, c.config.can_id, c.config.master_id, register, timeout_s, c.describe()))
    try:
        return MotorLimits(*values)
    except ValueError as exc:
        raise ArmError(f"motor {c.describe()} reports invalid limits {values}: {exc}; check its firmware "
                       "settings with the Damiao tool") from exc


def set_timeout(bus: CanBus, c: MotorChannel, timeout_s: float, reply_timeout_s: float) -> None:
    """Write the communication timeout of channel `c`'s motor (REG_TIMEOUT, in TIMEOUT_UNIT_S steps) and read it
    back; `c.timeout_s` then holds what the motor holds. ArmError naming the motor when it does not answer or holds
    another value."""
    steps = timeout_steps(timeout_s)
    who = c.describe()

    def reply(msg: can.Message) -> float | None:
        data = bytes(msg.data)
        if msg.arbitration_id == c.config.master_id and is_param_reply(data, c.config.can_id):
            answer = unpack_param_reply(data)
            return answer.value if answer.register == REG_TIMEOUT else None
        return None

    if request_reply(bus, PARAM_ID, param_write(c.config.can_id, REG_TIMEOUT, steps), reply, reply_timeout_s) is None:
        raise ArmError(f"motor {who} did not answer the write of its communication timeout (register {REG_TIMEOUT}) "
                       f"{REQUEST_ATTEMPTS} times within {reply_timeout_s * 1e3:.0f} ms: check its power, CAN id, "
                       "master id and the bus bitrate (`deploy arm scan`)")
    held = read_param(bus, c.config.can_id, c.config.master_id, REG_TIMEOUT, reply_timeout_s, who)
    if int(held) != steps:
        raise ArmError(f"motor {who} holds a communication timeout of {held * TIMEOUT_UNIT_S * 1e3:g} ms after "
                       f"{timeout_s * 1e3:g} ms was written (register {REG_TIMEOUT}, {TIMEOUT_UNIT_S * 1e6:g} us "
                       "steps): without it the motor would not disable itself when the bus is lost; update its "
                       "firmware with the Damiao tool")
    c.timeout_s = held * TIMEOUT_UNIT_S


def _is_feedback_of(msg: can.Message, master_id: int, can_id: int) -> bool:
    """True if `msg` came on the motor's master id and is not a parameter reply (so: a feedback frame)."""
    return msg.arbitration_id == master_id and not is_param_reply(bytes(msg.data), can_id)


def request_feedback(bus: CanBus, c: MotorChannel, data: bytes, arbitration_id: int, timeout_s: float,
                     now: Callable[[], float]) -> None:
    """Send a frame the motor answers with feedback and store the answer in `c` (REQUEST_ATTEMPTS x timeout_s),
    stamped with `now()`."""

    def reply(msg: can.Message) -> Feedback | None:
        if not _is_feedback_of(msg, c.config.master_id, c.config.can_id):
            return None
        return c.decode(bytes(msg.data))

    fb = request_reply(bus, arbitration_id, data, reply, timeout_s)
    if fb is None:
        raise ArmError(f"motor {c.describe()} did not answer {REQUEST_ATTEMPTS} times within {timeout_s * 1e3:.0f} "
                       "ms: check its power, CAN id, master id and the bus bitrate (`deploy arm scan`)")
    c.feedback, c.t_feedback = fb, now()


def receive_feedback(bus: CanBus, by_master: dict[int, MotorChannel], lock: threading.RLock,
                     now: Callable[[], float], wait_s: float) -> None:
    """Read feedback until every motor of `by_master` (master id -> channel) answered or `wait_s` passed (0: only
    the frames already queued); each answer is stored under `lock`, stamped with `now()`."""
    pending = set(by_master)
    deadline = time.perf_counter() + wait_s
    while pending:
        msg = bus.recv(max(0.0, deadline - time.perf_counter()))
        if msg is None:
            break
        c = by_master.get(msg.arbitration_id)
        if c is None:
            continue
        fb = c.decode(bytes(msg.data))
        if fb is None:
            continue  # a bad frame is ignored; a motor sending only bad frames goes stale in check_feedback
        with lock:
            c.feedback, c.t_feedback = fb, now()
        pending.discard(c.config.master_id)


def check_feedback(c: MotorChannel, age_s: float, watchdog: WatchdogConfig, tau_max: float | None) -> None:
    """ArmError if `c`'s feedback is older than the watchdog allows, reports a fault or a disabled motor, or (for
    a joint: `tau_max` given) a torque above tau_max x torque_margin."""
    timeout = watchdog.feedback_timeout_s
    if age_s > timeout:
        raise ArmError(
            f"watchdog: joint {c.describe()} sent no valid feedback for {age_s * 1e3:.0f} ms (limit "
            f"{timeout * 1e3:.0f} ms, {c.malformed} malformed frames): motors disabled; check the motor's "
            "power and CAN wiring, its master id, and the bus load")
    fb = c.feedback
    if fb.status.is_fault:
        raise ArmError(f"joint {c.describe()} reports {fb.status.name.lower().replace('_', '-')}: motors "
                       f"disabled; {fb.status.fix}, then `deploy arm enable --clear-errors`")
    if fb.status == Status.DISABLED:
        raise ArmError(f"joint {c.describe()} disabled itself (its CAN timeout or a power dip): motors "
                       "disabled; check its supply and that its CAN timeout is longer than the control period")
    if tau_max is not None:
        tau = abs(fb.tau)
        limit = tau_max * watchdog.torque_margin
        if tau > limit:
            raise ArmError(f"safety stop: joint {c.describe()} torque {tau:.1f} N m exceeds {limit:.1f} N m "
                           "(tau_max x torque_margin): motors disabled; the arm hit something or is blocked: "
                           "clear the obstacle, or lower the motion limits")


@dataclass(frozen=True)
class ScannedMotor:
    """A motor that answered a scan: its ids, status, the limits and communication timeout (s) its registers hold,
    and whether its feedback came in CAN FD frames."""

    can_id: int
    master_id: int
    status: str
    limits: MotorLimits
    timeout_s: float
    fd: bool

    def to_dict(self) -> dict:
        return {"can_id": self.can_id, "master_id": self.master_id, "status": self.status,
                "p_max": self.limits.p_max, "v_max": self.limits.v_max, "t_max": self.limits.t_max,
                "timeout_ms": round(self.timeout_s * 1e3, 1), "fd": self.fd}


def _status_reply(master_id: int, can_id: int, limits: MotorLimits) -> Callable[[can.Message], tuple | None]:
    """The scan's reply parser: the status name of the motor's first feedback frame ("malformed feedback" if bad)
    and whether it came as a CAN FD frame."""

    def reply(msg: can.Message) -> tuple[str, bool] | None:
        if not _is_feedback_of(msg, master_id, can_id):
            return None
        try:
            return unpack_feedback(bytes(msg.data), limits).status.name.lower(), bool(msg.is_fd)
        except FrameError:
            return "malformed feedback", bool(msg.is_fd)

    return reply


def scan_bus(bus: CanBus, ids: range, timeout_s: float = 0.02) -> list[ScannedMotor]:
    """Which CAN ids answer: each id's master id (register 7), PMAX/VMAX/TMAX, communication timeout and status
    (one feedback frame, requested without changing the motor's state), and whether it answered in CAN FD frames.
    Ids that do not answer are skipped."""
    found = []
    for can_id in ids:
        try:
            master = int(read_param(bus, can_id, None, REG_MST_ID, timeout_s, f"CAN id {can_id}"))
        except ArmError:
            continue
        values = [read_param(bus, can_id, master, r, timeout_s, f"CAN id {can_id}") for r in
                  (REG_PMAX, REG_VMAX, REG_TMAX, REG_TIMEOUT)]
        limits = MotorLimits(*values[:3])
        answer = request_reply(bus, PARAM_ID, refresh_request(can_id), _status_reply(master, can_id, limits),
                               timeout_s, attempts=1)
        status, fd = answer or ("no feedback", False)
        found.append(ScannedMotor(can_id, master, status, limits, values[3] * TIMEOUT_UNIT_S, fd))
    return found
