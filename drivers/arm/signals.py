"""SIGINT / SIGTERM handlers that make a device safe before the process stops."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """While installed, SIGINT and SIGTERM call `on_signal(name)` (e.g. "SIGTERM"), restore the previous
    handlers and raise KeyboardInterrupt (SIGINT) or SystemExit(128 + signal number) (SIGTERM)."""

    def __init__(self, on_signal: Callable[[str], None]) -> None:
        self._on_signal = on_signal
        self._old_handlers: dict[int, object] = {}

    @property
    def installed(self) -> bool:
        return bool(self._old_handlers)

    def install(self) -> None:
        """Install the handlers; does nothing outside the main thread (Python allows handlers only there) or
        when already installed."""
        if threading.current_thread() is not threading.main_thread() or self._old_handlers:
            return
        for sig in STOP_SIGNALS:
            self._old_handlers[sig] = signal.signal(sig, self._handle)

    def restore(self) -> None:
        """Put back the handlers that were there before `install()` (idempotent)."""
        for sig, handler in self._old_handlers.items():
            signal.signal(sig, handler)
        self._old_handlers.clear()

    def _handle(self, signum: int, _frame) -> None:
        self._on_signal(signal.Signals(signum).name)
        self.restore()
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)
