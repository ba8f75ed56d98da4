"""Ctrl-C and SIGTERM as one exception, `Interrupted`, raised where the program is, so that every layer on the
way out cleans up (the arm stops and disables its motors, a run folder is finished) and the command line then
prints what stopped.

`Interrupted` derives from BaseException, not KeyboardInterrupt: nothing that catches Exception or
KeyboardInterrupt (the CLI framework turns the latter into a silent exit 130) swallows it. Inside a `critical`
section (CAN I/O, one control cycle, a whole stop-disable-report sequence) the exception waits for the section's
end: an exception raised right after a lock was taken could leave it taken, and the disable that follows would
wait for it forever. Only the first signal raises: once an Interrupted was raised the program is on its way out,
and later signals (a second Ctrl-C) are recorded without cutting the cleanup short.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

SIGNAL_NAMES = {signal.SIGINT: "SIGINT (Ctrl-C)", signal.SIGTERM: "SIGTERM"}


class Interrupted(BaseException):  # noqa: N818 - it is not an error: the user stopped the program
    """SIGINT or SIGTERM arrived. `exit_code` is 128 + the signal number, as a shell reports it; `result` (an
    episode's partial result) and `run_dir` (its run folder, finished) are set by the code it passes through."""

    def __init__(self, signum: int, message: str | None = None) -> None:
        self.signum = int(signum)
        self.message = message or f"stopped by {SIGNAL_NAMES.get(signum, signal.Signals(signum).name)}"
        self.result: object | None = None
        self.run_dir: Path | None = None
        super().__init__(self.message)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    def __reduce__(self):  # crosses process boundaries (benchmark workers) with its signal
        return Interrupted, (self.signum, self.message)


_received: list[int] = []  # the signals received since `interrupts()` installed its handlers
_pending: list[int] = []  # a signal that came inside a critical section, raised when the section ends
_depth = [0]  # critical sections of the main thread currently open
_stopping = [False]  # an Interrupted was raised: later signals are only recorded
_MAIN = threading.main_thread().ident


def _raise_interrupted(signum: int, _frame: object) -> None:
    _received.append(signum)
    if _stopping[0]:
        return
    if _depth[0] > 0:
        _pending.append(signum)
        return
    _stopping[0] = True
    raise Interrupted(signum)


class _Critical:
    """`with critical:` marks code that must not be cut by an exception halfway (it holds locks that are not
    re-entrant, e.g. python-can's queues, or sends one control cycle): a signal arriving inside is raised as
    Interrupted when the outermost section ends (once: not when an Interrupted was raised already). Only the main
    thread counts (signals interrupt only it)."""

    def __enter__(self) -> None:
        if threading.get_ident() == _MAIN:
            _depth[0] += 1

    def __exit__(self, *exc: object) -> None:
        if threading.get_ident() != _MAIN:
            return
        _depth[0] -= 1
        if _depth[0] == 0 and _pending:
            signum = _pending.pop(0)
            _pending.clear()
            _stopping[0] = True
            raise Interrupted(signum)


critical = _Critical()


def received() -> int | None:
    """The first signal received while `interrupts()` was active (a C extension may have turned the Interrupted
    into another exception, e.g. an ImportError when the signal came during an import), None if none came."""
    return _received[0] if _received else None


def active() -> bool:
    """True while `interrupts()` has its handlers installed (SIGINT raises Interrupted)."""
    return signal.getsignal(signal.SIGINT) is _raise_interrupted


@contextmanager
def interrupts() -> Iterator[None]:
    """While inside: SIGINT and SIGTERM raise Interrupted where the main thread is; the previous handlers come
    back on leaving. Does nothing outside the main thread (Python allows handlers only there) or when already
    active."""
    if threading.current_thread() is not threading.main_thread() or active():
        yield
        return
    _received.clear()
    _pending.clear()
    _stopping[0] = False
    old = {sig: signal.signal(sig, _raise_interrupted) for sig in SIGNAL_NAMES}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)  # None: installed outside Python
