"""The arm's control cycles: `send()` commands, `on_cycle()`, `read()` feedback; realtime or lockstep.

- realtime (hardware, simulated motors with their own thread): `start()` runs the cycles in a thread at
  `rate_hz`, and `sync()` waits for the next one to end; a watchdog trips when a cycle starts more than
  `max_late_cycles` periods late. Starting lowers the interpreter's GIL switch interval to 0.2 ms
  (process-wide) so other threads cannot hold the loop off;
- lockstep (simulation on the caller's clock): `sync()` runs one cycle, so `on_cycle()` (one physics step)
  advances simulated time by one period per cycle.

An ArmError in a cycle trips the loop: the thread ends, `on_trip(fault)` runs (disable the motors; it returns the
fault, its message telling which motors were disabled) and the first fault is kept in `fault`.
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import ArmError
from drivers.interrupts import critical

GIL_SWITCH_INTERVAL_S = 2e-4  # Python's default 5 ms would let the planner thread delay a 2 ms control cycle


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


class ControlLoop:
    """Cycles of `send()` -> `on_cycle()` -> `read()` at `rate_hz`; `lock` guards the state they share with the
    caller (a cycle's end is signalled on it)."""

    def __init__(
        self,
        name: str,
        rate_hz: float,
        max_late_cycles: float,
        realtime: bool,
        send: Callable[[], None],
        read: Callable[[], None],
        on_trip: Callable[[ArmError], ArmError],
        on_cycle: Callable[[], None] | None = None,
    ) -> None:
        self.name = name
        self.rate_hz = rate_hz
        self.period_s = 1.0 / rate_hz
        self.max_late_cycles = max_late_cycles
        self.realtime = realtime
        self._send, self._read, self._on_trip, self._on_cycle = send, read, on_trip, on_cycle
        self.lock = threading.RLock()
        self._cycle_done = threading.Condition(self.lock)
        self.cycles = 0
        self.fault: ArmError | None = None
        self.stats = LoopStats()
        self._t0 = time.perf_counter()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def now(self) -> float:
        """The loop's clock (s): wall time since construction (realtime) or cycles x period (lockstep)."""
        return time.perf_counter() - self._t0 if self.realtime else self.cycles * self.period_s

    def clear_fault(self) -> None:
        self.fault = None

    def start(self) -> None:
        """Realtime: start the loop thread (lockstep: nothing to start)."""
        if not self.realtime:
            return
        sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_INTERVAL_S))
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"{self.name}-can-loop", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """End the loop thread (waits up to 1 s for it, unless called from it). Idempotent."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
        self._thread = None

    def sync(self, running: Callable[[], bool]) -> None:
        """Lockstep: run one cycle. Realtime: wait until the next cycle ended, a fault tripped the loop or
        `running()` turned false (at most 0.5 s + 10 periods)."""
        if not self.realtime:
            self.cycle()
            return
        with self._cycle_done:
            target = self.cycles + 1
            deadline = time.perf_counter() + 0.5 + 10 * self.period_s
            while self.cycles < target and self.fault is None and running():
                if not self._cycle_done.wait(max(0.0, deadline - time.perf_counter())):
                    break

    def trip(self, exc: ArmError) -> ArmError:
        """End the loop (waiting for its thread unless called from it, so no cycle reads the motors' answers to
        the disable), run `on_trip(exc)`, record the first fault and wake `sync()` waiters; returns the fault."""
        self.stop()
        fault = self._on_trip(exc)
        with self._cycle_done:
            if self.fault is None:
                self.fault = fault
            self._cycle_done.notify_all()
            return self.fault

    def cycle(self) -> None:
        """One cycle: send, on_cycle, read. An ArmError trips the loop and is raised."""
        if self.realtime:
            self.stats.starts.append(time.perf_counter())
        try:
            with critical:  # a signal waits for the cycle's end
                self._send()
                if self._on_cycle is not None:
                    self._on_cycle()
                self._read()
        except ArmError as exc:
            fault = self.trip(exc)
            if fault is exc:
                raise
            raise fault from exc
        with self._cycle_done:
            self.cycles += 1
            self._cycle_done.notify_all()

    def _run(self) -> None:
        period = self.period_s
        limit = self.max_late_cycles * period
        next_t = time.perf_counter()
        while not self._stop.is_set():
            late = time.perf_counter() - next_t
            if late > limit:
                self.trip(ArmError(
                    f"watchdog: control cycle started {late * 1e3:.1f} ms late (limit {limit * 1e3:.1f} ms, "
                    f"{self.rate_hz:.0f} Hz): motors disabled; the computer is overloaded: close "
                    "other programs, or lower control_rate_hz in the robot config"))
                return
            try:
                self.cycle()
            except ArmError:  # the cycle tripped the loop
                return
            except Exception as exc:  # noqa: BLE001 - the loop must end safe on any bug
                self.trip(ArmError(f"control loop crashed ({type(exc).__name__}: {exc}): motors disabled; "
                                   "please report this bug"))
                return
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))
