"""SIGTERM as an exception (veragmil_suite.utils.termination): what a console program and a study's stage use to
let go of what they hold when stopped."""

import os
import signal
import time

import pytest

from veragmil_suite.utils.termination import Terminated, sigterm_raises


def test_a_second_sigterm_does_not_break_off_the_unwinding_of_the_first():
    before = signal.getsignal(signal.SIGTERM)
    unwound = []
    with pytest.raises(Terminated), sigterm_raises():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        finally:  # a pool being closed, a file being finished
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)
            unwound.append(True)
    assert unwound
    assert signal.getsignal(signal.SIGTERM) is before
