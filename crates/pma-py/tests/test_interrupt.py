"""Ctrl-C stops a long run: the run checks Python's signals and raises KeyboardInterrupt.

The SIGINT comes from another process, as a terminal's or a notebook kernel manager's
does: a run holds the GIL, so a Python thread could not send it before the run ends.
"""
import os
import signal
import subprocess
import time

import pytest

import pma_exo


@pytest.mark.parametrize(
    "run",
    [
        lambda: pma_exo.single(duration=36000.0),
        lambda: pma_exo.simulate(duration=3600.0),
        lambda: pma_exo.sweep("monte_carlo"),
        lambda: pma_exo.fit_gait(iterations=100),
    ],
    ids=["single", "simulate", "sweep", "fit_gait"],
)
def test_sigint_raises_keyboard_interrupt(run):
    assert_interrupted(run, within_s=5.0)


def assert_interrupted(run, within_s):
    """SIGINT from another process 0.5 s into `run()` raises KeyboardInterrupt, within
    `within_s` of the start."""
    # Python raises KeyboardInterrupt only if SIGINT was not ignored when it started, and a
    # shell's background job starts with it ignored (regression: this test failed in a CI
    # launched as one): the handler a terminal's Python has is installed for the test.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    killer = subprocess.Popen(["sh", "-c", f"sleep 0.5; kill -INT {os.getpid()}"])
    start = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            run()
    finally:
        killer.wait()
        signal.signal(signal.SIGINT, previous)
    assert time.monotonic() - start < within_s
