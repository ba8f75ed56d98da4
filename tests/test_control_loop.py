"""The arm's control loop: lockstep cycles on the caller's clock, the realtime thread, its late-cycle watchdog,
and the first fault kept while every later cycle ends."""

import threading
import time

import pytest

from drivers.arm.control_loop import ControlLoop, LoopStats
from drivers.errors import ArmError


class Motors:
    """Records the loop's calls; `fail_on` makes the read of that cycle (from 1) raise `error`."""

    def __init__(self, fail_on: int | None = None, error: Exception | None = None, slow_on: int | None = None):
        self.calls: list[str] = []
        self.trips = 0
        self.fail_on, self.error, self.slow_on = fail_on, error, slow_on

    def send(self) -> None:
        self.calls.append("send")
        if self.calls.count("send") == self.slow_on:
            time.sleep(0.1)

    def read(self) -> None:
        self.calls.append("read")
        if self.calls.count("read") == self.fail_on:
            raise self.error

    def on_trip(self, fault: ArmError) -> ArmError:
        self.trips += 1
        return fault


def _loop(motors: Motors, realtime: bool, rate_hz: float = 100.0, max_late_cycles: float = 2.0, **kwargs):
    return ControlLoop("test", rate_hz, max_late_cycles, realtime, motors.send, motors.read, motors.on_trip, **kwargs)


def test_lockstep_runs_one_cycle_per_sync_with_on_cycle_between_send_and_read():
    motors = Motors()
    loop = _loop(motors, realtime=False, on_cycle=lambda: motors.calls.append("step"))
    loop.start()  # nothing to start in lockstep
    for _ in range(3):
        loop.sync(lambda: True)
    assert motors.calls == ["send", "step", "read"] * 3
    assert loop.cycles == 3 and loop.now() == pytest.approx(0.03) and loop.fault is None
    assert loop.stats.summary(loop.period_s) == {"cycles": 0}  # only realtime cycles are timed


def test_a_fault_trips_once_and_the_first_fault_is_kept():
    motors = Motors(fail_on=2, error=ArmError("joint2 reports over-current"))
    loop = _loop(motors, realtime=False)
    loop.sync(lambda: True)
    with pytest.raises(ArmError, match="over-current"):
        loop.sync(lambda: True)
    assert motors.trips == 1 and loop.cycles == 1 and "over-current" in str(loop.fault)
    loop.trip(ArmError("stopped by SIGTERM"))
    assert motors.trips == 2 and "over-current" in str(loop.fault)
    loop.clear_fault()
    assert loop.fault is None


def test_realtime_loop_runs_at_its_rate_until_stopped():
    motors = Motors()
    loop = _loop(motors, realtime=True, max_late_cycles=50.0)
    loop.start()
    try:
        time.sleep(0.2)
        before = loop.cycles
        loop.sync(lambda: True)
        assert loop.cycles > before and loop.fault is None
    finally:
        loop.stop()
    ended = loop.cycles
    time.sleep(0.05)
    assert loop.cycles == ended and not any(t.name == "test-can-loop" for t in threading.enumerate())
    stats = loop.stats.summary(loop.period_s)
    assert stats["cycles"] == ended and 50.0 < stats["loop_hz"] < 110.0
    assert loop.now() > 0.2  # wall clock in realtime


def test_realtime_watchdog_trips_on_a_late_cycle():
    motors = Motors(slow_on=3)  # one 100 ms cycle: the next starts 9 periods late
    loop = _loop(motors, realtime=True, max_late_cycles=5.0)
    loop.start()
    time.sleep(0.3)
    loop.sync(lambda: True)  # returns at once: the loop has tripped
    assert "watchdog: control cycle started" in str(loop.fault) and "(limit 50.0 ms, 100 Hz)" in str(loop.fault)
    assert motors.trips == 1
    loop.stop()


def test_a_bug_in_a_cycle_ends_the_loop_safe():
    motors = Motors(fail_on=2, error=ZeroDivisionError("division by zero"))
    loop = _loop(motors, realtime=True, max_late_cycles=50.0)
    loop.start()
    time.sleep(0.2)
    assert "control loop crashed (ZeroDivisionError: division by zero)" in str(loop.fault) and motors.trips == 1
    loop.stop()


def test_sync_stops_waiting_when_the_arm_is_no_longer_running():
    loop = _loop(Motors(), realtime=True)  # never started: no cycle will come
    t0 = time.perf_counter()
    loop.sync(lambda: False)
    assert time.perf_counter() - t0 < 0.1


def test_loop_stats_summary():
    stats = LoopStats()
    stats.starts.extend([0.0, 0.010, 0.021, 0.030])
    summary = stats.summary(0.01)
    assert summary["cycles"] == 4 and summary["loop_hz"] == pytest.approx(100.0)
    assert summary["period_ms_median"] == pytest.approx(10.0) and summary["jitter_ms_p99"] == pytest.approx(1.0, 0.02)
