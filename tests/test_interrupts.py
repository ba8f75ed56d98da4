"""Ctrl-C and SIGTERM as `Interrupted`: raised where the main thread is, held back to the end of a critical
section, the previous handlers restored after."""

import os
import pickle
import signal

import pytest

from drivers.interrupts import Interrupted, active, critical, interrupts, received


@pytest.mark.parametrize(("sig", "code", "words"), [(signal.SIGINT, 130, "stopped by SIGINT (Ctrl-C)"),
                                                    (signal.SIGTERM, 143, "stopped by SIGTERM")])
def test_a_signal_raises_interrupted_and_the_old_handlers_come_back(sig, code, words):
    before = signal.getsignal(sig)
    with pytest.raises(Interrupted) as caught, interrupts():
        assert active()
        os.kill(os.getpid(), sig)  # the handler runs as the call returns
        pytest.fail("not interrupted")
    assert caught.value.exit_code == code and str(caught.value) == words and received() == sig
    assert signal.getsignal(sig) is before and not active()


def test_inside_a_critical_section_the_signal_waits_for_its_end():
    steps = []
    with pytest.raises(Interrupted), interrupts():
        with critical:
            with critical:
                os.kill(os.getpid(), signal.SIGTERM)
                steps.append("inner done")
            steps.append("outer done")
        steps.append("after the section")  # not reached: raised as the outer section ended
    assert steps == ["inner done", "outer done"]


def test_nested_interrupts_are_one_and_it_crosses_processes():
    with interrupts():
        handler = signal.getsignal(signal.SIGINT)
        with interrupts():
            assert signal.getsignal(signal.SIGINT) is handler
        assert active()
    copy = pickle.loads(pickle.dumps(Interrupted(signal.SIGTERM)))
    assert copy.exit_code == 143 and copy.message == "stopped by SIGTERM"
