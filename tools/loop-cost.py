#!/usr/bin/env python3
"""The closed loop's instructions per 1 ms period against rapier's own step (issue 50).

Runs `pma-exo simulate SCENARIO --duration S` under valgrind's callgrind, collecting only
inside the run loop (`LegSim::run_until_fault`: no start-up, no pre-run checks), and
prints per period:

- the run loop's instructions;
- rapier's step, inclusive: everything `PhysicsWorld::step` executes, the libm and libc
  calls it makes among them (the multibody's `sincos`, the solver's `memset`);
- the closed loop over rapier's step, and the same split by function name (rapier, parry,
  nalgebra and glam against the rest: libm and libc called inside rapier's step count
  as the rest there, which is why it reads higher).

    python3 tools/loop-cost.py [--bin PMA_EXO] [--duration S] [SCENARIO ...]

Instruction counts do not depend on the machine's load; one 9 s run of the two-leg
trainer takes about 40 s. Needs valgrind (`apt install valgrind`).
"""
import argparse
import os
import pathlib
import re
import subprocess
import sys
import tempfile

RAPIER_NAMES = re.compile(r"rapier3d::|parry|nalgebra|glam")


def rows(text):
    """(instructions, `file:function`) of each function row of callgrind_annotate."""
    for line in text.splitlines():
        m = re.match(r"\s*([\d,]+) \(.*?\)\s+(\S.*)", line)
        if m:
            yield int(m.group(1).replace(",", "")), m.group(2)


def function(row):
    """The function's name of a `file:function [object]` row."""
    return re.sub(r" \[[^\]]*\]$", "", row.split(":", 1)[-1])


def annotate(out, inclusive):
    args = ["callgrind_annotate", "--auto=no", "--threshold=100", out]
    if inclusive:
        args.insert(1, "--inclusive=yes")
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def cost(binary, scenario, duration_s):
    """The run loop's, rapier's step's and the by-name rapier instructions per period."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        subprocess.run(
            ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
             "--toggle-collect=*LegSim::run_until_fault*",
             binary, "simulate", scenario, "--duration", str(duration_s)],
            check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if not os.path.exists(out):
            sys.exit(f"valgrind did not run {binary} simulate {scenario}")
        inclusive = list(rows(annotate(out, True)))
        exclusive = rows(annotate(out, False))
    # A function's inclusive cost is its largest row: callgrind_annotate splits an inlined
    # function by source file, and which row carries the `[object]` mark depends on the
    # build's paths (a build in the repository's own target/ marked a 108-instruction row).
    loop = max((n for n, f in inclusive if function(f) == "pma_leg::sim::run::LegSim::run_until_fault"),
               default=0)
    rapier = max((n for n, f in inclusive
                  if function(f) == "rapier3d::pipeline::physics_world::PhysicsWorld::step"),
                 default=0)
    named = sum(n for n, f in exclusive if RAPIER_NAMES.search(function(f)))
    if loop == 0 or rapier == 0:
        sys.exit(f"no run loop or no rapier step in the profile of {scenario}")
    periods = duration_s * 1000
    return loop / periods, rapier / periods, named / periods


def main():
    root = pathlib.Path(__file__).resolve().parents[1]
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", root / "target"))
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenarios", nargs="*", default=["gait_treadmill"])
    p.add_argument("--bin", default=str(target / "release/pma-exo"))
    p.add_argument("--duration", type=float, default=9.0,
                   help="simulated seconds (at least two strides)")
    a = p.parse_args()
    if not os.access(a.bin, os.X_OK):
        sys.exit(f"not an executable: {a.bin} (cargo build --release)")
    print("| scenario | instructions per period | rapier's step | closed loop / rapier's step "
          "| the rest by name | closed loop / rapier by name |")
    print("|---|---|---|---|---|---|")
    for s in a.scenarios:
        loop, rapier, named = cost(a.bin, s, a.duration)
        print(f"| `{s}` | {loop:,.0f} | {rapier:,.0f} | {loop / rapier:.3f} "
              f"| {loop - named:,.0f} | {loop / named:.3f} |")


if __name__ == "__main__":
    main()
