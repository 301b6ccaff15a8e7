"""Bench: a controller written in Python steps the muscle behind the rig's supervisor."""
import math

import numpy as np
import pytest

import pma_exo


class Pid:
    """The gains of models/gains/muscle/pid.toml, a backward-difference velocity, and the
    Rust PID's conditional integration: no integrating into a saturated command (without
    it the load winds past the supervisor's window on the exact plant step)."""

    kp, ki, kd, bias = 1081891546.6254396, 24101111748.72039, 190.52099358330702, 0.0

    def __init__(self, resting_pa, x0, period, p_max):
        self.integral = (resting_pa - self.bias) / self.ki
        self.previous, self.period, self.p_max = x0, period, p_max
        self.saturated = 0

    def __call__(self, x_ref, v_ref, x):
        e = x_ref - x
        if not (self.saturated * e > 0):
            self.integral += e * self.period
        v = (x - self.previous) / self.period
        self.previous = x
        u = self.bias + self.kp * e + self.ki * self.integral + self.kd * (v_ref - v)
        self.saturated = 1 if u > self.p_max else (-1 if u < 0.0 else 0)
        return min(max(u, 0.0), self.p_max)


def test_a_python_pid_tracks_the_paper_sine():
    bench = pma_exo.Bench(plant="ideal")
    x = bench.reset()
    p_max = bench.limits["pressure_max_pa"]
    pid = Pid(bench.command, x, bench.period, p_max)
    w = 2 * math.pi * 0.25
    errors = []
    for k in range(1, 8001):
        t = k * bench.period
        x_ref, v_ref = 0.015 - 0.015 * math.cos(w * t), 0.015 * w * math.sin(w * t)
        bench.write(pid(x_ref, v_ref, x))
        x = bench.step()
        errors.append(abs(0.015 - 0.015 * math.cos(w * bench.time) - bench.state()["position_m"]))
    assert bench.time == pytest.approx(8.0)
    assert max(errors[4000:]) < 1e-3


@pytest.mark.parametrize("controller", ["aprc-ndo", "pid"])
def test_replaying_single_s_commands_reproduces_its_run(controller):
    """Bench is single's bench: the commands of a `single` run, written period by period,
    give its positions bit for bit (the paper's sine starts at 15 mm)."""
    run = pma_exo.single(plant="ideal", controller=controller, duration=5.0)
    bench = pma_exo.Bench("ideal", position=0.015)
    positions = [bench.step()]
    for command in run["pressure_cmd_pa"][:-1]:
        assert bench.write(command) == command
        positions.append(bench.step())
    np.testing.assert_array_equal(positions, run["position_m"])
    np.testing.assert_array_equal(positions, run["measured_m"])


def test_commands_are_checked_and_rate_limited():
    bench = pma_exo.Bench()
    limits = bench.limits
    for bad in (math.nan, math.inf, -1.0, limits["pressure_max_pa"] + 1.0):
        with pytest.raises(pma_exo.PmaError, match="pressure command"):
            bench.write(bad)
    with pytest.raises(TypeError):
        bench.write("3 bar")
    with pytest.raises(TypeError):
        bench.write(np.array([1e5, 2e5]))
    resting = bench.command
    applied = bench.write(limits["pressure_max_pa"])
    step = limits["pressure_rate_max_pa_per_s"] * bench.period
    assert applied == pytest.approx(resting + step)


def test_the_muscle_cannot_be_driven_past_its_window():
    """Full pressure, then vented: the load leaves the position window one way or the
    other; the supervisor vents and raises, and the fault latches until reset()."""
    bench = pma_exo.Bench()
    lo, hi = bench.limits["position_min_m"], bench.limits["position_max_m"]
    with pytest.raises(pma_exo.SupervisorError, match="position-out"):
        for pressure in (bench.limits["pressure_max_pa"], 0.0):
            for _ in range(5000):
                bench.write(pressure)
                x = bench.step()
                assert lo <= x <= hi
    assert bench.state()["pressure_pa"] < bench.limits["pressure_max_pa"]
    with pytest.raises(pma_exo.SupervisorError, match="reset"):
        bench.step()
    with pytest.raises(pma_exo.SupervisorError):
        bench.read()
    assert bench.reset() == pytest.approx(0.0)
    assert bench.time == 0.0
    bench.step()


def test_bad_benches_raise():
    with pytest.raises(pma_exo.PmaError, match="unknown plant"):
        pma_exo.Bench(plant="no_such_plant")
    with pytest.raises(pma_exo.PmaError, match="period_s"):
        pma_exo.Bench(period=1.0)
    with pytest.raises(pma_exo.PmaError, match="position"):
        pma_exo.Bench(position=math.nan)
