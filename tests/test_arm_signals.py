"""StopSignals: SIGINT / SIGTERM run the safe-stop callback, restore the old handlers, then end the program."""

import os
import signal
import threading
import time

import pytest

from drivers.arm.signals import StopSignals


@pytest.mark.parametrize(("sig", "raised", "code"), [(signal.SIGTERM, SystemExit, 128 + signal.SIGTERM),
                                                     (signal.SIGINT, KeyboardInterrupt, None)])
def test_a_stop_signal_calls_back_restores_and_raises(sig, raised, code):
    before = signal.getsignal(sig)
    names = []
    signals = StopSignals(names.append)
    signals.install()
    assert signals.installed and signal.getsignal(sig) is not before
    with pytest.raises(raised) as info:
        os.kill(os.getpid(), sig)
        time.sleep(1.0)  # the handler runs here
    assert names == [sig.name] and not signals.installed and signal.getsignal(sig) is before
    if code is not None:
        assert info.value.code == code


def test_restore_puts_back_the_old_handlers():
    before = signal.getsignal(signal.SIGTERM)
    signals = StopSignals(lambda _name: None)
    signals.install()
    signals.install()  # idempotent: the saved handlers stay the original ones
    signals.restore()
    signals.restore()
    assert signal.getsignal(signal.SIGTERM) is before


def test_outside_the_main_thread_nothing_is_installed():
    signals = StopSignals(lambda _name: None)
    errors = []

    def install() -> None:
        try:
            signals.install()
        except ValueError as exc:  # what signal.signal raises outside the main thread
            errors.append(exc)

    worker = threading.Thread(target=install)
    worker.start()
    worker.join()
    assert not errors and not signals.installed
