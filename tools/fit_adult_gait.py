#!/usr/bin/env python3
"""Derives crates/pma-leg/models/gait/fukuchi2018.toml: the adult treadmill reference.

Source: Fukuchi C.A., Fukuchi R.K., Duarte M. (2018), "A public data set of overground and
treadmill walking kinematics and kinetics in healthy individuals", PeerJ 6:e4640, data on
figshare (doi 10.6084/m9.figshare.5722711), CC BY 4.0: 42 adults (24 young, 18 older) on an
instrumented treadmill at eight speeds; the slow conditions T01..T05 are used here. Their
per-subject files (`WBDSxxwalkT0Yang.txt`, joint angles, and `WBDSxxwalkT0Yknt.txt`, joint
moments and ground reaction forces, each 101 samples over the gait cycle from initial
contact) are averaged over subjects, both sides per subject, into the JSON this script
reads. That averaging step and its JSON are not in the repository (they were made by a
helper whose work was lost with its machine; only T01 made it into fukuchi2018.toml):
redoing them from the figshare files is open work of issue 27, and until then T01 can be
checked against the paper's figures only.

Each condition gives:
- `speed_m_s`: the subjects' mean treadmill speed;
- `toe_off`: the mean phase where the vertical GRF falls below 0.05 BW after mid-stance;
- hip, knee and ankle angles (deg; flexion, flexion, dorsiflexion positive) as Fourier
  series of HARMONICS harmonics (least squares over the 100 samples 0..99 %, the 100 %
  sample repeating 0 %), with the fit's residual;
- the mean curves at 0, 1, ..., 100 % for comparison: joint moments (N m/kg, internal,
  extensor / plantarflexor positive) and the vertical and fore-aft ground reaction (body
  weights, forward positive).

Usage: python3 tools/fit_adult_gait.py fukuchi2018_slow.json > crates/pma-leg/models/gait/fukuchi2018.toml
"""
import json
import math
import sys

HARMONICS = 6
ANGLES = {"hip": "hip_flexion_deg", "knee": "knee_flexion_deg", "ankle": "ankle_dorsiflexion_deg"}
CURVES = {
    "hip_deg": "hip_flexion_deg",
    "knee_deg": "knee_flexion_deg",
    "ankle_deg": "ankle_dorsiflexion_deg",
    "hip_moment_nm_kg": "hip_moment_ext_Nm_kg",
    "knee_moment_nm_kg": "knee_moment_ext_Nm_kg",
    "ankle_moment_nm_kg": "ankle_moment_pf_Nm_kg",
    "grf_vertical_bw": "grf_vertical_BW",
    "grf_fore_aft_bw": "grf_fore_aft_BW",
}


def fit(y101):
    """Least-squares Fourier fit over the equally spaced samples 0..99 % (the DFT's
    coefficients below the Nyquist harmonic)."""
    y = y101[:-1]
    n = len(y)
    phase = [i / n for i in range(n)]
    a = [sum(y) / n]
    b = [0.0]
    for k in range(1, HARMONICS + 1):
        a.append(2.0 / n * sum(v * math.cos(2 * math.pi * k * p) for v, p in zip(y, phase)))
        b.append(2.0 / n * sum(v * math.sin(2 * math.pi * k * p) for v, p in zip(y, phase)))

    def model(p):
        return a[0] + sum(
            a[k] * math.cos(2 * math.pi * k * p) + b[k] * math.sin(2 * math.pi * k * p)
            for k in range(1, HARMONICS + 1)
        )

    resid = [model(p) - v for v, p in zip(y, phase)]
    return a, b, math.sqrt(sum(r * r for r in resid) / n), max(abs(r) for r in resid)


def numbers(v, digits=5):
    return "[" + ", ".join(f"{x:.{digits}f}" for x in v) + "]"


def main():
    data = json.load(open(sys.argv[1]))["conditions"]
    print("# The adult treadmill reference: Fukuchi, Fukuchi & Duarte (2018), PeerJ 6:e4640, data")
    print("# doi 10.6084/m9.figshare.5722711 (CC BY 4.0), 42 adults on an instrumented treadmill,")
    print("# both sides averaged per subject, then over subjects. Derived by tools/fit_adult_gait.py")
    print("# (its header says how). Angles: theta(phi) = a0 + sum_k a_k cos(2 pi k phi) + b_k sin(2 pi k phi),")
    print("# phase 0 = initial contact; flexion (ankle: dorsiflexion) positive. Curves: 101 samples at")
    print("# 0, 1, ..., 100 % of the cycle; moments internal, extensor (ankle: plantarflexor) positive.")
    print(f"harmonics = {HARMONICS}")
    for cond in sorted(data):
        c = data[cond]
        curves = c["curves"]
        print()
        print(f"[{cond.lower()}]")
        print(f"# {c['n_subjects']} subjects; speed sd {c['speed_m_s']['sd']:.3f} m/s; toe-off sd {c['toe_off_pct']['side_avg']['sd'] / 100:.4f}")
        print(f"speed_m_s = {c['speed_m_s']['mean']:.4f}")
        print(f"subjects = {c['n_subjects']}")
        print(f"toe_off = {c['toe_off_pct']['side_avg']['mean'] / 100:.4f}")
        for joint, key in ANGLES.items():
            y = curves[key]["side_avg"]["mean"]
            a, b, rms, worst = fit(y)
            print()
            print(f"[{cond.lower()}.{joint}]")
            print(f"# fit residual over the 100 samples: RMS {rms:.3f} deg, max {worst:.3f} deg")
            print(f"cos_deg = {numbers(a)}")
            print(f"sin_deg = {numbers(b)}")
        print()
        print(f"[{cond.lower()}.curves]")
        for name, key in CURVES.items():
            print(f"{name} = {numbers(curves[key]['side_avg']['mean'], 4)}")
        print()
        print(f"[{cond.lower()}.sd]")
        for name, key in CURVES.items():
            print(f"{name} = {numbers(curves[key]['side_avg']['sd'], 4)}")


if __name__ == "__main__":
    main()
