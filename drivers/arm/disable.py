"""Disabling every motor and knowing which ones did: a Damiao motor answers a disable with a feedback frame whose
status is no longer "enabled", so a disable counts only once that answer came. A motor that never answers (a
bus-off, a silent or unpowered motor, lost frames) may still be enabled, and every message says so by name, unless
its communication timeout was set at enable and read back (drivers/arm/motor_channels.py `set_timeout`): once no
command has reached it for that long it has disabled itself (`wait_for_timeouts`), and the messages say so, with
the timeout as the cause.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable

from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import Special, Status, is_param_reply, special
from drivers.arm.motor_channels import MotorChannel
from drivers.errors import ArmError
from drivers.interrupts import critical

DISABLE_ROUNDS = 3  # a motor whose answer did not come is sent the disable again, this often in all
MOTORS_DISABLED = "motors disabled"  # the words fault messages use for "every motor was disabled"


def disable_and_confirm(bus: CanBus, channels: Iterable[MotorChannel], timeout_s: float, lock: threading.RLock,
                        now: Callable[[], float], rounds: int = DISABLE_ROUNDS) -> list[MotorChannel]:
    """Send disable to every motor and wait up to `timeout_s` for each one's answer (stored as its feedback,
    under `lock`, stamped with `now()`); resend to the silent ones, `rounds` sends in all. Returns the channels
    that never confirmed. Never raises: a dead bus only means nobody confirms; a signal waits for its end."""
    with critical:
        return _disable(bus, list(channels), timeout_s, lock, now, rounds)


def _disable(bus: CanBus, channels: list[MotorChannel], timeout_s: float, lock: threading.RLock,
             now: Callable[[], float], rounds: int) -> list[MotorChannel]:
    pending = {c.config.master_id: c for c in channels}
    for _ in range(rounds):
        for c in pending.values():
            try:
                bus.send(c.config.can_id, special(Special.DISABLE))
            except ArmError:  # bus-off, full queue: the motor counts as unconfirmed
                pass
        deadline = time.perf_counter() + timeout_s
        while pending and (remaining := deadline - time.perf_counter()) > 0:
            try:
                msg = bus.recv(remaining)
            except ArmError:  # an error frame: keep listening until the deadline
                time.sleep(min(remaining, 1e-3))
                continue
            if msg is None:
                break
            c = pending.get(msg.arbitration_id)
            if c is None or is_param_reply(bytes(msg.data), c.config.can_id):
                continue
            fb = c.decode(bytes(msg.data))
            if fb is None:
                continue
            with lock:
                c.feedback, c.t_feedback = fb, now()
            if fb.status != Status.ENABLED:
                del pending[c.config.master_id]
        if not pending:
            break
    try:
        bus.flush()
    except ArmError:
        pass
    return list(pending.values())


def wait_for_timeouts(channels: Iterable[MotorChannel], last_command_s: float) -> list[MotorChannel]:
    """The motors of `channels` (whose disable went unanswered) that hold a communication timeout: wait until that
    long has passed since `last_command_s` (time.perf_counter of the last command sent to any motor: none reached
    them later), after which each has disabled itself. Never raises; a signal waits for its end."""
    timed = [c for c in channels if c.timeout_s]
    if timed:
        with critical:
            time.sleep(max(0.0, last_command_s + max(c.timeout_s for c in timed) - time.perf_counter()))
    return timed


def motor_states(channels: Iterable[MotorChannel], unconfirmed: set[str],
                 timed_out: frozenset[str] | set[str] = frozenset()) -> list[dict]:
    """Every motor's final state as the driver knows it: name, CAN id, enabled (True where a disable was not
    confirmed: it may still be), status (the last feedback's, "no answer" where a disable went unanswered, "timed
    out" where it went unanswered but the motor's communication timeout has since disabled it: then `cause` says
    so)."""
    states = []
    for c in channels:
        fb = c.feedback
        if c.name in timed_out:
            ms = round(c.timeout_s * 1e3, 1)
            states.append({"name": c.name, "can_id": c.config.can_id, "enabled": False, "status": "timed out",
                           "timeout_ms": ms, "cause": f"its disable went unanswered, but no command has reached it for "
                           f"its {ms:g} ms communication timeout: it has disabled itself"})
        elif c.name in unconfirmed:
            states.append({"name": c.name, "can_id": c.config.can_id, "enabled": True, "status": "no answer"})
        else:
            status = fb.status.name.lower().replace("_", "-") if fb is not None else "no feedback"
            states.append({"name": c.name, "can_id": c.config.can_id,
                           "enabled": fb is not None and fb.status == Status.ENABLED, "status": status})
    return states


def disable_summary(states: list[dict]) -> str:
    """"all N motors disabled" (and which disabled themselves by their timeout), or the motors that may still be
    enabled and what to do about them."""
    left = _still_enabled(states)
    return _all_disabled(states) if not left else _not_disabled(left, len(states))


def with_summary(message: str, states: list[dict]) -> str:
    """`message` telling the truth about the motors, built from their states: when every motor confirmed, the
    message as it is if it says "motors disabled", else with the count added; when some disabled themselves by
    their timeout or may still be enabled, the words "motors disabled" (or the message's end) say so. Idempotent."""
    left, timed = _still_enabled(states), _timed_out(states)
    if not left and not timed:
        return message if MOTORS_DISABLED in message else f"{message}; {disable_summary(states)}"
    outcome = disable_summary(states)
    if outcome in message:  # already told (the CLI may add the states of an error the driver reported)
        return message
    before, said, after = message.partition(MOTORS_DISABLED)
    return f"{before}{outcome}{after}" if said else f"{message}; {outcome}"


def _all_disabled(states: list[dict]) -> str:
    timed = _timed_out(states)
    if not timed:
        return f"all {len(states)} {MOTORS_DISABLED}"
    ms = max(s["timeout_ms"] for s in states if s.get("status") == "timed out")
    if len(timed) == len(states):
        return (f"all {len(states)} {MOTORS_DISABLED}: none answered the disable, but each has disabled itself by "
                f"its own {ms:g} ms communication timeout, no command having reached it for that long")
    one = len(timed) == 1
    return (f"all {len(states)} {MOTORS_DISABLED}: {', '.join(timed)} did not answer the disable but "
            f"{'has disabled itself by its' if one else 'have disabled themselves by their'} own {ms:g} ms "
            f"communication timeout, no command having reached {'it' if one else 'them'} for that long")


def _timed_out(states: list[dict]) -> list[str]:
    """The motors that did not answer the disable but have disabled themselves by their communication timeout."""
    return [s["name"] for s in states if s.get("status") == "timed out"]


def _still_enabled(states: list[dict]) -> list[str]:
    """The motors whose disable went unconfirmed (they may still be enabled)."""
    return [s["name"] for s in states if s["enabled"]]


def _not_disabled(left: list[str], motors: int) -> str:
    """What happened when the motors `left` (of `motors`) did not confirm the disable, and what to do."""
    if len(left) == motors:
        return (f"no motor answered the disable ({', '.join(left)}): all may still be enabled: switch off their "
                "power")
    its = "its" if len(left) == 1 else "their"
    return (f"{MOTORS_DISABLED} except {', '.join(left)}, which did not answer the disable and may still be "
            f"enabled: switch off {its} power")
