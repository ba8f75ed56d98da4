"""A background thread that keeps only the latest frame of a stream, so a slow consumer never lags; the work that
makes a `Frame` of it is spent only on the frames read."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from drivers.camera.base import Frame


class LatestFrameReader:
    """Calls `poll(timeout_s) -> item | None` in a thread and keeps the newest item.

    `read(timeout_s)` returns `finish(item)` (default: the item itself, a Frame) for an item newer than the last one
    it returned, or None on timeout; `finish` runs in the reading thread, on the items read only (a camera's
    post-processing and alignment). An exception raised by `poll` (a vanished device) stops the thread and is
    re-raised by `read`.
    """

    def __init__(self, poll: Callable[[float], Any], finish: Callable[[Any], Frame] = lambda item: item,
                 poll_timeout_s: float = 0.1) -> None:
        self._poll, self._finish = poll, finish
        self._poll_timeout_s = poll_timeout_s
        self._cond = threading.Condition()
        self._latest: Any = None
        self._serial = 0  # frames received
        self._served = 0  # value of _serial when read() last returned
        self._error: BaseException | None = None
        self._running = True
        self._thread = threading.Thread(target=self._run, name="camera-reader", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while self._running:
            try:
                item = self._poll(self._poll_timeout_s)
            except BaseException as exc:  # noqa: BLE001 (handed to the reading thread)
                with self._cond:
                    self._error = exc
                    self._cond.notify_all()
                return
            if item is not None:
                with self._cond:
                    self._latest, self._serial = item, self._serial + 1
                    self._cond.notify_all()

    @property
    def latest(self) -> Frame | None:
        """The newest frame received so far (whether or not `read` returned it); None before the first."""
        with self._cond:
            latest = self._latest
        return None if latest is None else self._finish(latest)

    def read(self, timeout_s: float) -> Frame | None:
        """The latest frame not yet returned, waiting up to `timeout_s`; None if none came."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while self._serial == self._served and self._error is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cond.wait(remaining)
            if self._serial == self._served:
                raise self._error  # type: ignore[misc]
            self._served = self._serial
            latest = self._latest
        return self._finish(latest)

    def stop(self) -> None:
        """Stop and join the thread (idempotent)."""
        self._running = False
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
