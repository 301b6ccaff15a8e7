#!/usr/bin/env python3
"""Whole-process speed of the runs issue 30 pins (docs/benchmarks.md): 60 s simulated,
median of 5 runs each; wall time (perf_counter around the process) and CPU time (user +
sys of the child, getrusage), and real time over each.

    python3 tools/speed.py [PMA_EXO_BINARY ...]   # default target/release/pma-exo

With several binaries (two builds to compare) their runs alternate, so that this noisy
machine's drift falls on all of them alike, and a table follows per binary.
"""
import argparse
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import time

CASES = [
    "single --duration 60",
    "simulate gait_training --duration 60",
    "simulate gait_treadmill_one_leg --duration 60",
    "simulate gait_treadmill --duration 60",
]
RUNS = 5


def timed(binary, args):
    """Wall and CPU seconds of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([binary, *args], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main():
    root = pathlib.Path(__file__).resolve().parents[1]
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", root / "target"))
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("binaries", nargs="*", metavar="PMA_EXO_BINARY",
                   help="builds to compare (default: $CARGO_TARGET_DIR/release/pma-exo)")
    binaries = p.parse_args().binaries or [str(target / "release/pma-exo")]
    missing = [b for b in binaries if not os.access(b, os.X_OK)]
    if missing:
        sys.exit(f"not an executable: {', '.join(missing)}")
    results = {b: {case: [] for case in CASES} for b in binaries}
    for case in CASES:
        for _ in range(RUNS):
            for b in binaries:
                results[b][case].append(timed(b, case.split()))
    for b in binaries:
        if len(binaries) > 1:
            print(f"\n{b}:")
        print("| run (60 s simulated, median of 5) | wall | real time | CPU | real time on CPU |")
        print("|---|---|---|---|---|")
        for case in CASES:
            wall = statistics.median(r[0] for r in results[b][case])
            cpu = statistics.median(r[1] for r in results[b][case])
            print(f"| `pma-exo {case}` | {wall * 1e3:.1f} ms | {60 / wall:.0f}x | "
                  f"{cpu * 1e3:.1f} ms | {60 / max(cpu, 1e-4):.0f}x |")


if __name__ == "__main__":
    main()
