#!/usr/bin/env python3
"""MuJoCo and the rapier leg side by side: the cost of one 1 ms control period of the
in-air leg (crates/pma-leg/models/exo_leg.urdf, fixed pelvis, hip and knee), measured in
one run of this script on this machine.

- MuJoCo: the URDF through MuJoCo's compiler, a torque motor on each joint, gravity, the
  URDF's joint limits; `mj_step` in MuJoCo's own C loop (`mj_step(m, d, nstep=N)`), Euler,
  at 1, 2 and the in-air scenarios' `physics_substeps` (64 since stop 74) steps per period, the last
  the ratios' base (rapier's in-air rows take as many); the torques a
  smooth function held over each timed block, as the muscles' torques are held over a
  period. Median of REPEATS blocks of N periods.
- rapier: `cargo bench -p pma-leg --bench leg` (criterion, release; pma-leg's bench, which
  does not build Rerun) for `rapier_bare` (the same
  leg, the scenario's substeps, torques set each period) and `closed_loop_x100` (rapier + 4 muscles +
  4 APRC-NDO controllers + references, 100 periods per iteration); the point estimates of
  their means from criterion's JSON.

- The two-leg trainer (crates/pma-leg/models/exo_trainer.urdf: the pelvis on its two
  slides, two legs of hip, knee and passive ankle, n = 8), standing on both feet at 30 %
  body-weight support: in MuJoCo as tools/mujoco/stance.py builds it (its four foot spheres
  on a floor, position servos on hips and knees, the orthoses as joint springs,
  implicit-fast) at one step per period; in rapier `rapier_treadmill_bare_2_leg` (the
  treadmill scenarios' physics substeps, pma-leg's own foot contacts) and
  `closed_loop_treadmill_x100` (gait_treadmill: eight muscles and controllers, the gait's
  references and figures).

    python3 tools/mujoco/speed.py [--skip-bench]   # --skip-bench: read the last bench's JSON

Prints two Markdown tables (docs/benchmarks.md quotes them).
"""
import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tomllib
import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
URDF = ROOT / "crates/pma-leg/models/exo_leg.urdf"
PERIOD_S = 1e-3
N = 20_000
REPEATS = 7
BENCHES = ("rapier_bare", "closed_loop_x100", "rapier_treadmill_bare_2_leg",
           "closed_loop_treadmill_x100")


def model(substeps):
    """The in-air leg in MuJoCo: a motor per joint, Euler at PERIOD_S / substeps."""
    robot = ET.fromstring(URDF.read_text())
    ext = ET.SubElement(robot, "mujoco")
    ET.SubElement(ext, "compiler", discardvisual="true", fusestatic="false",
                  balanceinertia="false")
    spec = mujoco.MjSpec.from_string(ET.tostring(robot, encoding="unicode"))
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.timestep = PERIOD_S / substeps
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    for j in spec.joints:
        j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act = spec.add_actuator(name=j.name, target=j.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.gainprm[0] = 1.0  # a torque motor: ctrl in N m
    return spec.compile()


def mujoco_us_per_period(substeps):
    """Median cost of one period (us): blocks of N periods, torques held per block."""
    m = model(substeps)
    d = mujoco.MjData(m)
    times = []
    for r in range(REPEATS):
        a = np.sin(0.4 * r)
        d.ctrl[:] = [20.0 * a, 5.0 * a][: m.nu]
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=N * substeps)
        times.append((time.perf_counter() - t0) / N * 1e6)
        if not np.all(np.isfinite(d.qpos)):
            sys.exit("MuJoCo's leg went non-finite")
    return statistics.median(times), m.nv


def mujoco_trainer_us():
    """Median cost of one 1 ms period (us) of the two-leg trainer standing in MuJoCo."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    import stance

    m, total, _ = stance.build(75.0, 2)
    tilt = stance.hip_pitch_rad()
    flat = (tilt + math.radians(stance.SHANK_VERTICAL[0]), math.radians(stance.SHANK_VERTICAL[1]))
    d, _ = stance.settle(m, [flat, flat], 0.3, total)
    m.opt.timestep = PERIOD_S
    hold = d.ctrl.copy()
    times = []
    for r in range(REPEATS):
        # A sway of the servos' set-points (+-0.05 rad), held per block: the feet stay down.
        d.ctrl[:] = hold + 0.05 * np.sin(0.4 * r)
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=N)
        times.append((time.perf_counter() - t0) / N * 1e6)
        if not np.all(np.isfinite(d.qpos)):
            sys.exit("MuJoCo's trainer went non-finite")
    return statistics.median(times), m.nv, d.ncon


def physics_substeps(scenario):
    """`physics_substeps` of an embedded scenario: the steps the bench's rows take."""
    path = ROOT / "crates/pma-leg/models/scenarios" / f"{scenario}.toml"
    return tomllib.loads(path.read_text())["physics_substeps"]


def rapier_us(skip_bench):
    """The rapier leg's bare step and closed-loop period (us) from criterion's JSON."""
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if not skip_bench:
        subprocess.run(
            ["cargo", "bench", "-p", "pma-leg", "--bench", "leg", "--",
             "rapier_bare|closed_loop_x100$|rapier_treadmill_bare_2_leg|closed_loop_treadmill_x100",
             "--warm-up-time", "1", "--measurement-time", "5", "--noplot"],
            cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    out = {}
    for name in BENCHES:
        path = target / "criterion/leg_period_1ms" / name / "new/estimates.json"
        ns = json.loads(path.read_text())["mean"]["point_estimate"]
        out[name] = ns / 1e3 / (100 if name.endswith("_x100") else 1)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--skip-bench", action="store_true",
                   help="read the last `cargo bench -p pma-leg --bench leg` results instead of running it")
    args = p.parse_args()
    rapier = rapier_us(args.skip_bench)
    rows = []
    in_air = physics_substeps("gait_training")
    steps = sorted({1, 2, in_air})
    for substeps in steps:
        us, nv = mujoco_us_per_period(substeps)
        rows.append((f"MuJoCo {mujoco.__version__}, `mj_step` x{substeps} (Euler, {nv} dof)", us))
    base = rows[steps.index(in_air)][1]
    rows.append((f"rapier, bare step ({in_air} substeps)", rapier["rapier_bare"]))
    rows.append(("rapier leg, closed loop (4 muscles, 4 APRC-NDO)", rapier["closed_loop_x100"]))
    table("1 ms period of the in-air leg", f"/ MuJoCo x{in_air}", rows, base)
    us, nv, ncon = mujoco_trainer_us()
    print()
    table("1 ms period of the two-leg trainer, standing", "/ MuJoCo", [
        (f"MuJoCo {mujoco.__version__}, `mj_step` x1 (implicit-fast, {nv} dof, "
         f"{ncon} contacts)", us),
        (f"rapier, bare step ({physics_substeps('gait_treadmill')} substeps, the feet's contacts)",
         rapier["rapier_treadmill_bare_2_leg"]),
        ("rapier trainer, closed loop (8 muscles, 8 APRC-NDO, `gait_treadmill`)",
         rapier["closed_loop_treadmill_x100"]),
    ], us)


def table(title, ratio, rows, base_us):
    """A Markdown table of `rows` (name, us per period): real time and the ratio to
    `base_us`."""
    print(f"| {title} | us | real time | {ratio} |")
    print("|---|---|---|---|")
    for name, us in rows:
        print(f"| {name} | {us:.2f} | {1e3 / us:.0f}x | {us / base_us:.2f} |")


if __name__ == "__main__":
    main()
