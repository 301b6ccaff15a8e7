"""A run releases the GIL: it runs on a worker thread while the calling one waits with the
GIL released, so other Python threads go on (a notebook's widgets, a progress thread)."""
import threading
import time

import pytest

import pma_exo


# Each run only has to last well over 0.1 s (the assertion below); the in-air ones take about
# their simulated time at the shipped 64 physics substeps (pendulum at 60 s took 62 s of a CI).
@pytest.mark.parametrize(
    "run",
    [
        lambda: pma_exo.single(duration=2000.0),
        lambda: pma_exo.simulate(duration=10.0),
        lambda: pma_exo.pendulum(duration=5.0),
        lambda: pma_exo.size("gait_treadmill"),
    ],
    ids=["single", "simulate", "pendulum", "size"],
)
def test_another_thread_runs_meanwhile(run):
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.001)

    ticker = threading.Thread(target=tick)
    ticker.start()
    start = time.monotonic()
    try:
        run()
    finally:
        end = time.monotonic()
        done.set()
        ticker.join()
    during = sum(start < t < end for t in ticks)
    # A run that held the GIL would let the ticker tick not once; released, it ticks about
    # once a millisecond (sleep's overshoot aside).
    assert end - start > 0.1, "too short a run to tell"
    assert during > 0.2 * (end - start) / 0.001, (during, end - start)
