"""How fast a controller written in Python drives the Rust plant: periods per second of a
PID in Python on `Bench` and a PD in Python on `Leg`, against the same runs with the
controller in Rust, and the cost of one period from Python: the Rust run's own commands
replayed through `write` + `step`, the same physics as the Rust loop's. Not a test:
figures for docs/python.md.

    python crates/pma-py/benchmarks/pid_speed.py [--repeat 5]
"""
import argparse
import math
import statistics
import time

import numpy as np

import pma_exo

W = 2 * math.pi * 0.25  # the paper's sine: 15 + 15 sin(W t) mm
X0 = 0.015  # where the paper's sine starts, as `single` puts the load


class Pid:
    """models/gains/muscle/pid.toml's gains, a backward-difference velocity, and the Rust
    PID's conditional integration (no integrating into a saturated command)."""

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


def python_pid_on_bench(periods):
    bench = pma_exo.Bench("ideal", position=X0)
    x = bench.reset()
    p_max, dt = bench.limits["pressure_max_pa"], bench.period
    pid = Pid(bench.command, x, dt, p_max)
    start = time.perf_counter()
    for k in range(1, periods + 1):
        t = k * dt
        u = pid(X0 + 0.015 * math.sin(W * t), 0.015 * W * math.cos(W * t), x)
        bench.write(u)
        x = bench.step()
    return periods / (time.perf_counter() - start)


def replay_on_bench(duration):
    """`single`'s PID commands through write + step (which reproduces its positions
    exactly: tests/test_bench.py)."""
    commands = pma_exo.single(plant="ideal", controller="pid", duration=duration)["pressure_cmd_pa"].tolist()
    bench = pma_exo.Bench("ideal", position=X0)
    start = time.perf_counter()
    bench.step()
    for u in commands[:-1]:
        bench.write(u)
        bench.step()
    return len(commands) / (time.perf_counter() - start)


def rust_single(duration):
    start = time.perf_counter()
    run = pma_exo.single(plant="ideal", controller="pid", duration=duration)
    wall = time.perf_counter() - start
    periods = run["metrics"]["samples"]
    return periods / wall, run["metrics"]["real_time_factor"] * 1000.0


def python_pd_on_leg(periods, kp=1e7, kd=1e5):
    leg = pma_exo.Leg("gait_training")
    resting, p_max, dt = leg.command.copy(), leg.limits["pressure_max_pa"], leg.period
    q = leg.read()
    previous = q.copy()
    start = time.perf_counter()
    for _ in range(periods):
        e = leg.reference(leg.time + dt) - q
        u = kp * e - kd * (q - previous) / dt
        previous = q
        p = resting + np.stack([u[:, 0], -u[:, 0], u[:, 1], -u[:, 1]], axis=1) / 2
        leg.write(np.clip(p, 0.0, p_max))
        q = leg.step()
    return periods / (time.perf_counter() - start)


def replay_on_leg(duration):
    """`simulate`'s PID commands through write + step."""
    run = pma_exo.simulate("gait_training", controller="pid", duration=duration)
    leg = pma_exo.Leg("gait_training")
    commands = np.stack([run[f"{m}_pressure_cmd_pa"] for m in leg.muscles], axis=1)
    start = time.perf_counter()
    leg.step()
    for u in commands[:-1]:
        leg.write(u)
        leg.step()
    return len(commands) / (time.perf_counter() - start)


def rust_simulate(duration):
    start = time.perf_counter()
    run = pma_exo.simulate("gait_training", controller="pid", duration=duration)
    wall = time.perf_counter() - start
    return len(run["t_s"]) / wall, run["metrics"]["real_time_factor"] * 1000.0


def best(f, repeat):
    """The median of `repeat` runs (each a tuple or a number)."""
    runs = [f() for _ in range(repeat)]
    if isinstance(runs[0], tuple):
        return tuple(statistics.median(r[i] for r in runs) for i in range(len(runs[0])))
    return statistics.median(runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    a = parser.parse_args()
    rows = []
    py_bench = best(lambda: python_pid_on_bench(20_000), a.repeat)
    bare_b = best(lambda: replay_on_bench(20.0), a.repeat)
    rust_b, rust_b_loop = best(lambda: rust_single(20.0), a.repeat)
    rows += [
        ("bench: PID in Python on Bench (20 s of the sine)", py_bench),
        ("bench: write + step from Python (the Rust PID's commands replayed)", bare_b),
        ("bench: PID in Rust, pma_exo.single (call, arrays included)", rust_b),
        ("bench: PID in Rust, the loop alone (real_time_factor)", rust_b_loop),
    ]
    py_leg = best(lambda: python_pd_on_leg(4_000), a.repeat)
    bare_l = best(lambda: replay_on_leg(4.0), a.repeat)
    rust_l, rust_l_loop = best(lambda: rust_simulate(4.0), a.repeat)
    rows += [
        ("leg: PD in Python on Leg (4 s of gait_training)", py_leg),
        ("leg: write + step from Python (the Rust PID's commands replayed)", bare_l),
        ("leg: PID in Rust, pma_exo.simulate (call, arrays included)", rust_l),
        ("leg: PID in Rust, the loop alone (real_time_factor)", rust_l_loop),
    ]
    print("| run | periods/s | us/period |")
    print("|---|---:|---:|")
    for name, rate in rows:
        print(f"| {name} | {rate:,.0f} | {1e6 / rate:.2f} |")
    print()
    print(f"bench: one write + step from Python costs {1e6 / bare_b - 1e6 / rust_b_loop:.2f} us beyond the Rust period")
    print(f"leg: one write + step from Python costs {1e6 / bare_l - 1e6 / rust_l_loop:.2f} us beyond the Rust period")


if __name__ == "__main__":
    main()
