#!/usr/bin/env python3
"""The trainer's geometry against the adult reference: the pelvis frame's tilt and the
stride period that crates/pma-leg/models/exo_trainer.urdf and the scenarios ship.

The reference's angles are measured relative to the subjects' pelvis; the exoskeleton's
pelvis does not pitch, so the tilt of its frame decides where the reference puts the feet.
For each tilt this prints, from the adult reference's mean curves (fukuchi2018.toml) on
the URDF's segments (thigh 0.429 m, shank 0.4305 m, heel and ball spheres of 0.03 m at
(-0.04, -0.038) and (0.13, -0.038) m from the ankle):
- in double support (0-16 % of the cycle), how much higher the leading foot's lowest point
  is than the trailing foot's (mm): positive lands late, negative takes the load early;
- the least clearance of the swing foot over the stance foot's sole in terminal swing
  (80-100 %, mm), before the compliant contact's penetration (about 15 mm) is taken off.
Then the stride period at which the stance foot, rolling heel to ball as the reference
turns it, travels back at the data's walking speed: the belt's speed at that period
equals the subjects' (the stance foot's fore-aft sweep over the stance, less the rolling,
divided by the stance time).

Usage: python3 tools/trainer_geometry.py [CONDITION] [TILT_DEG]   (default t01, 6.5)
"""
import math
import pathlib
import sys
import tomllib

MODELS = pathlib.Path(__file__).resolve().parents[1] / "crates/pma-leg/models"
THIGH, SHANK, R = 0.429, 0.4305, 0.03
SPHERES = {"heel": (-0.04, -0.038), "ball": (0.13, -0.038)}


def rot(p, a):
    """A rotation about -Y by `a`: (x, z) -> (x cos a - z sin a, x sin a + z cos a)."""
    return (p[0] * math.cos(a) - p[1] * math.sin(a), p[0] * math.sin(a) + p[1] * math.cos(a))


class Leg:
    def __init__(self, curves, tilt_deg):
        self.hip, self.knee, self.ankle = (curves[k] for k in ("hip_deg", "knee_deg", "ankle_deg"))
        self.tilt = math.radians(tilt_deg)

    def pose(self, i):
        """Ankle (x, z) in the pelvis frame and the foot's pitch (rad, toe up) at sample i."""
        i %= 100
        th = math.radians(self.hip[i]) - self.tilt
        sh = th - math.radians(self.knee[i])
        ankle = (THIGH * math.sin(th) + SHANK * math.sin(sh), -(THIGH * math.cos(th) + SHANK * math.cos(sh)))
        return ankle, sh + math.radians(self.ankle[i])

    def lowest(self, i):
        (x, z), beta = self.pose(i)
        return min(z + rot(p, beta)[1] - R for p in SPHERES.values())


def stride_period(leg, toe_off, speed_m_s):
    """The period at which the stance foot's contact sphere (heel while the foot is toe-up,
    ball once it is toe-down) moves back at `speed_m_s`, rolling as the foot turns."""
    n = int(math.floor(toe_off * 100))
    target = leg.pose(n)[0][0]

    def end_x(travel):
        (x, _), beta = leg.pose(0)
        sphere = "heel" if beta > 0 else "ball"
        centre = x + rot(SPHERES[sphere], beta)[0]
        for k in range(1, n + 1):
            _, b0 = leg.pose(k - 1)
            _, b1 = leg.pose(k)
            now = "heel" if b1 > 0 else "ball"
            if now != sphere:
                # The other sphere takes over where the foot is now (both touch as the
                # foot passes level).
                sphere, centre = now, x + rot(SPHERES[now], b0)[0]
            centre += -travel / 100 - R * (b1 - b0)
            x = centre - rot(SPHERES[sphere], b1)[0]
        return x

    lo, hi = 0.0, 5.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if end_x(mid) > target else (lo, mid)
    travel = 0.5 * (lo + hi)
    return travel / speed_m_s, travel


def main():
    cond = sys.argv[1] if len(sys.argv) > 1 else "t01"
    chosen = float(sys.argv[2]) if len(sys.argv) > 2 else 6.5
    data = tomllib.loads((MODELS / "gait/fukuchi2018.toml").read_text())[cond]
    print(f"{cond}: {data['speed_m_s']:.3f} m/s, toe-off {data['toe_off']:.4f}")
    for tilt in [4, 5, 6, 6.5, 7, 8, 9, 10, 11.05, 12]:
        leg = Leg(data["curves"], tilt)
        gaps = [1000 * (leg.lowest(p) - leg.lowest(p + 50)) for p in (0, 4, 8, 12, 16)]
        clearance = min(1000 * (leg.lowest(p) - leg.lowest(p - 50)) for p in range(80, 100))
        mark = "  <- shipped" if abs(tilt - chosen) < 1e-9 else ""
        print(f"tilt {tilt:5.2f} deg: leading minus trailing foot in double support at 0/4/8/12/16 %: "
              + " ".join(f"{g:6.1f}" for g in gaps) + f" mm; terminal-swing clearance {clearance:5.1f} mm{mark}")
    leg = Leg(data["curves"], chosen)
    period, travel = stride_period(leg, data["toe_off"], data["speed_m_s"])
    print(f"at tilt {chosen} deg the belt travels {travel:.4f} m per cycle: stride period {period:.4f} s "
          f"({120 / period:.1f} steps/min) for {data['speed_m_s']:.3f} m/s")


if __name__ == "__main__":
    main()
