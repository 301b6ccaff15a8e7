#!/usr/bin/env python3
"""Independent MuJoCo cross-check of a static stance of the treadmill leg.

Loads crates/pma-leg/models/exo_leg_foot.urdf into MuJoCo, puts the patient's carried mass
on the pelvis and the body-weight support (BWS) force on it, holds hip and knee with stiff
position servos, lets the pelvis slide settle on a floor at z = 0, and reports the contact
forces and the holding torques at static equilibrium. See tools/mujoco/README.md.

    python3 tools/mujoco/stance.py [--body-mass-kg 75] [--json]
"""
import argparse
import json
import math
import pathlib
import sys

import mujoco
import numpy as np

G = 9.80665  # pma_model::GRAVITY_M_S2, not MuJoCo's default 9.81
URDF = pathlib.Path(__file__).resolve().parents[2] / "crates/pma-leg/models/exo_leg_foot.urdf"
# Winter's fractions of this leg's human segments (thigh, leg, foot), as pma-leg's
# patient_on_pelvis: everything else of the patient rides on the pelvis.
CARRIED_FRACTION = 1.0 - 0.100 - 0.0465 - 0.0145
BWS_FRACTIONS = (0.0, 0.3, 0.5)
# The URDF pitches the hip's origin by the pelvis's anterior tilt: at this hip flexion the
# thigh hangs vertical.
TILT_DEG = math.degrees(0.1929)
# Shank vertical and foot flat (thigh 5.73 deg forward, knee 5.73 deg); heel only (thigh
# 20 deg forward, knee 10); ball only (thigh 10 deg back, knee 5); crouched on the ball
# (thigh 10 deg forward, knee 20). Every knee off its stop at 0, which the simulation keeps.
POSES_DEG = ((TILT_DEG + math.degrees(0.1), math.degrees(0.1)), (TILT_DEG + 20.0, 10.0),
             (TILT_DEG - 10.0, 5.0), (TILT_DEG + 10.0, 20.0))
DT = 0.0005
# Servo stiffness only sets how far the pose sags before the set-point correction below
# removes the sag; kv is about critical for the shank-and-foot inertia about the knee.
KP, KV = 2.0e4, 200.0
SLIDE_DAMPING = 2000.0  # N s/m, settling only; removed for the final rounds


def build(body_mass_kg):
    """The URDF as MuJoCo reads it, plus floor, patient mass and servos. Returns the model
    and the mass the belt and harness carry (kg)."""
    text = URDF.read_text()
    head = '<robot name="exo_leg_foot">'
    if head not in text:
        sys.exit(f"{URDF}: no {head!r} to hang MuJoCo's compiler options on")
    # fusestatic=false keeps the foot a body of its own behind the fixed ankle (its inertia
    # as written, and the contact forces on it by name); balanceinertia=false so that an
    # inertia violating the triangle inequality fails loudly instead of being altered.
    text = text.replace(head, head + '<mujoco><compiler discardvisual="true" '
                        'fusestatic="false" balanceinertia="false"/></mujoco>', 1)
    spec = mujoco.MjSpec.from_string(text)
    spec.option.gravity = [0.0, 0.0, -G]
    spec.option.timestep = DT
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # kv implicit: stable
    # Frictionless (condim 1): pma-leg's smooth Coulomb friction is zero at zero slip, so at
    # a true static equilibrium the belt pushes only vertically; MuJoCo's friction cone would
    # instead hold whatever tangential force the settling history left.
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[2.0, 2.0, 0.1], contype=0, conaffinity=1, condim=1)
    for g in spec.geoms:
        if g.name == "floor":
            continue
        if g.type == mujoco.mjtGeom.mjGEOM_SPHERE:  # the foot's contact spheres
            g.name = "heel" if g.pos[0] < 0 else "ball"
            g.contype, g.conaffinity, g.condim = 1, 0, 1
        else:  # pelvis box and thigh cylinder: never in contact with anything
            g.contype, g.conaffinity = 0, 0
    pelvis = spec.body("pelvis")
    pelvis.mass += body_mass_kg * CARRIED_FRACTION
    for j in spec.joints:
        # Statics only: the knee pose 0 sits on its URDF stop (a limit force there would take
        # part of the holding torque), and the URDF's effort 200 N m would clip the servo.
        j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if j.name == "pelvis_x":
            # The harness's fore-aft spring; frictionless, nothing pushes it off its rest.
            j.stiffness = [2000.0, 0.0, 0.0]
    for name in ("hip", "knee"):
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=KP, kv=KV)
    model = spec.compile()
    # What the belt and harness carry: the pelvis and everything below it (the fore-aft
    # trolley above it hangs on the frame).
    total = float(model.body_subtreemass[model.body("pelvis").id])
    return model, total


def foot_contacts(m, d):
    """Per sphere: world force on the foot (N) and contact point (m)."""
    out = {}
    for i in range(d.ncon):
        c = d.contact[i]
        f6 = np.zeros(6)
        mujoco.mj_contactForce(m, d, i, f6)
        # The contact frame's first row is the normal from geom1 to geom2, and the force
        # acts on geom2: flip it when the sphere is geom1.
        f = c.frame.reshape(3, 3).T @ f6[:3]
        sphere = c.geom2 if m.geom(c.geom1).name == "floor" else c.geom1
        sign = 1.0 if sphere == c.geom2 else -1.0
        out[m.geom(sphere).name] = (sign * f, c.pos.copy(), -c.dist)
    return out


def statics_torques(m, d, contacts):
    """Holding torques (flexion positive) from the bodies' COMs and the contact forces by
    moment balance of the links below each joint: independent of the servo's output."""
    tau = {}
    for jname, below in (("hip", ("thigh", "shank", "foot")), ("knee", ("shank", "foot"))):
        j = m.joint(jname).id
        anchor, axis = d.xanchor[j], d.xaxis[j]
        moment = np.zeros(3)
        for b in below:
            moment += np.cross(d.body(b).xipos - anchor, [0, 0, -m.body(b).mass[0] * G])
        for f, p, _ in contacts.values():
            moment += np.cross(p - anchor, f)
        tau[jname] = -float(axis @ moment)  # the servo cancels what gravity and belt apply
    return tau


def settle(m, hip_deg, knee_deg, bws, total):
    d = mujoco.MjData(m)
    slide, hip, knee = (m.joint(n).qposadr[0] for n in ("pelvis_z", "hip", "knee"))
    target = np.radians([hip_deg, knee_deg])
    d.qpos[[hip, knee]] = target
    # Start with the lowest sphere just touching the belt.
    mujoco.mj_kinematics(m, d)
    spheres = [m.geom(n).id for n in ("heel", "ball")]
    d.qpos[slide] = -min(d.geom_xpos[g][2] - m.geom_size[g][0] for g in spheres)
    d.ctrl[:] = target
    pelvis = m.body("pelvis").id
    d.xfrc_applied[pelvis, 2] = bws * total * G  # constant-force harness
    weight = (1.0 - bws) * total * G
    dof = m.joint("pelvis_z").dofadr[0]
    m.dof_damping[dof] = SLIDE_DAMPING
    for rnd in range(60):
        if rnd == 20:
            m.dof_damping[dof] = 0.0  # the equilibrium must hold without the settling aid
        for _ in range(2000):
            mujoco.mj_step(m, d)
        pose_err = target - d.qpos[[hip, knee]]
        # The servo sags by torque/kp; shifting its set-point by the sag holds the pose exactly.
        d.ctrl[:] += pose_err
        mujoco.mj_forward(m, d)
        fz = sum(f[2] for f, _, _ in foot_contacts(m, d).values())
        if (rnd > 20 and np.abs(pose_err).max() < 1e-9 and np.abs(d.qvel).max() < 1e-8
                and abs(fz - weight) < 1e-6 * weight):
            break
    m.dof_damping[dof] = 0.0
    return d, rnd + 1


def case(m, total, body_mass_kg, hip_deg, knee_deg, bws):
    d, rounds = settle(m, hip_deg, knee_deg, bws, total)
    contacts = foot_contacts(m, d)
    fz = {n: float(contacts[n][0][2]) if n in contacts else 0.0 for n in ("heel", "ball")}
    total_fz = fz["heel"] + fz["ball"]
    weight = (1.0 - bws) * total * G
    servo = {n: float(d.actuator(n).force[0]) for n in ("hip", "knee")}
    hand = statics_torques(m, d, contacts)
    return {
        "hip_deg": hip_deg, "knee_deg": knee_deg,
        "bws_fraction": bws, "body_mass_kg": body_mass_kg,
        "carried_on_pelvis_kg": body_mass_kg * CARRIED_FRACTION,
        "total_mass_kg": total,
        "expected_vertical_n": weight,
        "vertical_n": total_fz,
        "vertical_error_pct": 100.0 * (total_fz - weight) / weight,
        "heel_vertical_n": fz["heel"], "ball_vertical_n": fz["ball"],
        "heel_share": fz["heel"] / total_fz if total_fz > 0 else float("nan"),
        "horizontal_n": float(sum(f[0] for f, _, _ in contacts.values())),
        "hip_torque_nm": servo["hip"], "knee_torque_nm": servo["knee"],
        "hip_torque_statics_nm": hand["hip"], "knee_torque_statics_nm": hand["knee"],
        "pelvis_z_m": float(d.qpos[m.joint("pelvis_z").qposadr[0]]),
        "hip_height_m": float(d.xanchor[m.joint("hip").id][2]),
        "penetration_m": {n: float(c[2]) for n, c in contacts.items()},
        "max_abs_qvel": float(np.abs(d.qvel).max()),
        "pose_error_rad": float(np.abs(np.radians([hip_deg, knee_deg])
                                       - d.qpos[[m.joint("hip").qposadr[0],
                                                 m.joint("knee").qposadr[0]]]).max()),
        "settle_s": rounds * 2000 * DT,
    }


def check(rows, path):
    """Compares `rows` with the cases in `path`; a message (non-zero exit) if they moved."""
    keys = ("vertical_n", "heel_vertical_n", "ball_vertical_n", "hip_torque_nm", "knee_torque_nm")
    old = json.loads(pathlib.Path(path).read_text())["cases"]
    if len(old) != len(rows):
        return f"{path}: {len(old)} cases, now {len(rows)}: regenerate it with --json"
    for a, b in zip(old, rows):
        for k in keys:
            scale = max(abs(a["vertical_n"]) * 0.01, abs(a[k]))
            if abs(a[k] - b[k]) > 1e-3 * scale:
                return (f"{path}: hip {b['hip_deg']:.2f} knee {b['knee_deg']:.2f} bws "
                        f"{b['bws_fraction']}: {k} {a[k]} there, {b[k]} now: regenerate it")
    print(f"{path}: the {len(rows)} cases agree within 0.1 %")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--body-mass-kg", type=float, default=75.0)
    ap.add_argument("--json", action="store_true", help="JSON on stdout instead of a table")
    ap.add_argument("--check", metavar="FILE",
                    help="compare with an earlier --json output (CI: tools/mujoco/stance.json, "
                         "which tests/treadmill_mujoco.rs reads); exit 1 if a force or torque "
                         "moved by more than 0.1 %%")
    args = ap.parse_args()
    m, total = build(args.body_mass_kg)
    rows = [case(m, total, args.body_mass_kg, h, k, b)
            for b in BWS_FRACTIONS for h, k in POSES_DEG]
    bad = [r for r in rows if abs(r["vertical_error_pct"]) > 0.5]
    if args.check:
        sys.exit(check(rows, args.check))
    if args.json:
        urdf = str(URDF.relative_to(URDF.parents[3]))
        json.dump({"mujoco": mujoco.__version__, "urdf": urdf, "gravity": G, "cases": rows},
                  sys.stdout, indent=1)
        print()
    else:
        print(f"MuJoCo {mujoco.__version__}, {URDF.name}, body mass {args.body_mass_kg} kg, "
              f"total {total:.4f} kg, g {G}")
        print(f"{'hip':>6} {'knee':>6} {'bws':>4} {'(1-b)mg N':>10} {'Fz N':>10} "
              f"{'heel N':>9} {'ball N':>9} {'heel%':>6} {'hip Nm':>8} {'knee Nm':>8} "
              f"{'statics':>15} {'pelvis_z':>9}")
        for r in rows:
            print(f"{r['hip_deg']:6.2f} {r['knee_deg']:6.2f} {r['bws_fraction']:4.1f} "
                  f"{r['expected_vertical_n']:10.3f} {r['vertical_n']:10.3f} "
                  f"{r['heel_vertical_n']:9.3f} {r['ball_vertical_n']:9.3f} "
                  f"{100 * r['heel_share']:6.1f} {r['hip_torque_nm']:8.3f} "
                  f"{r['knee_torque_nm']:8.3f} "
                  f"{r['hip_torque_statics_nm']:7.3f} {r['knee_torque_statics_nm']:7.3f} "
                  f"{r['pelvis_z_m']:9.5f}")
    if bad:
        sys.exit(f"not at equilibrium (vertical force off by > 0.5 %): {len(bad)} case(s)")


if __name__ == "__main__":
    main()
