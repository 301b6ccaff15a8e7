#!/usr/bin/env python3
"""Independent MuJoCo cross-check of the trainer's static stances, one leg and two.

Loads crates/pma-leg/models/exo_trainer.urdf into MuJoCo (both legs, or the right one with
the left removed), puts the patient's carried mass on the pelvis and the body-weight
support (BWS) force on it, holds hips and knees with stiff position servos, leaves each
ankle to its orthosis (a joint spring within its stops), lets the pelvis settle on a
frictionless floor at z = 0, and reports each foot's vertical force, its heel's share and
each leg's holding torques at static equilibrium. See tools/mujoco/README.md.

    python3 tools/mujoco/stance.py [--body-mass-kg 75] [--json | --check FILE]
"""
import argparse
import json
import math
import pathlib
import sys
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

G = 9.81  # pma_model::GRAVITY_M_S2 (MuJoCo's default too; not standard gravity)
ROOT = pathlib.Path(__file__).resolve().parents[2]
URDF = ROOT / "crates/pma-leg/models/exo_trainer.urdf"
# Winter's fractions of one leg's human segments (thigh, leg, foot), as pma-leg's
# patient_on_pelvis: everything else of the patient rides on the pelvis.
LEG_MASS_FRACTION = 0.100 + 0.0465 + 0.0145
# The passive ankle's orthosis: the scenario's [treadmill.ankle] defaults (pma-leg's
# AnkleSettings::default(), crates/pma-leg/src/ground.rs).
ANKLE = {"stiffness_nm_per_rad": 100.0, "damping_nm_s_per_rad": 1.0, "rest_deg": 5.0,
         "range_deg": [-15.0, 15.0]}
# The harness's fore-aft spring and damper on `pelvis_x` (the rapier test's), and the
# vertical slide's damper while it settles; neither carries force at rest.
FORE_AFT_N_PER_M, FORE_AFT_N_S_PER_M = 2000.0, 600.0
SLIDE_DAMPING_N_S_PER_M = 2000.0
BWS_FRACTIONS = (0.0, 0.3, 0.5)
SIDES = ("right", "left")
DT = 0.0005
# Servo stiffness only sets how far the pose sags before the set-point correction below
# removes the sag; kv is about critical for the shank-and-foot inertia about the knee.
KP, KV = 2.0e4, 200.0
STEPS_PER_CORRECTION = 100
MAX_SECONDS = 60.0
# The contacts and the ankles' stops as near-rigid constraints (time constant 4 steps,
# impedance 0.99): a sphere carrying 868 N sinks 0.68 mm instead of MuJoCo's default 2.6 mm,
# and a stop taking 100 N m gives 0.01 deg instead of 5 deg. MuJoCo then computes the
# rigid-contact statics; what a compliant contact's sinkage changes is pma-leg's test's
# business (README: "What depends on the contact").
STIFF_SOLREF = [0.002, 1.0]
STIFF_SOLIMP = [0.99, 0.99, 0.001, 0.5, 2.0]


# Poses: the thigh's angle forward of vertical and the knee's flexion (deg); the hip's
# flexion adds the URDF's pelvis tilt. The shank leans forward by thigh - knee, the foot
# pitches (toes up) by that plus its ankle's dorsiflexion. The orthosis is soft (100 N m/rad)
# against a body weight on one sphere, so a foot on its heel or ball needs its shank well
# tilted to keep the other sphere off the floor.
SHANK_VERTICAL = (math.degrees(0.1), math.degrees(0.1))
# On the heel: its moment plantarflexes the ankle (to -5.7 deg at 0 % BWS); the shank
# leaning 30 deg forward keeps the toes up by 24 deg or more.
ON_THE_HEEL = (35.0, 5.0)
# On the ball: its moment dorsiflexes the ankle onto its +15 deg stop at every BWS; the
# shank leaning 30 deg back keeps the heel up by 15 deg (44 mm).
ON_THE_BALL = (-10.0, 20.0)
CROUCHED_ON_THE_BALL = (10.0, 40.0)
# Double support: the leading leg on its heel, the trailing one on its ball, both ankles
# on their springs (neither on a stop), so the split between the feet follows from the two
# orthoses' springs and the geometry.
LEADING_HEEL = (25.0, 5.0)
TRAILING_BALL = (-18.0, 20.0)

ONE_LEG = (("foot flat", (SHANK_VERTICAL,)), ("heel only", (ON_THE_HEEL,)),
           ("ball only", (ON_THE_BALL,)), ("crouched on the ball", (CROUCHED_ON_THE_BALL,)))
TWO_LEGS = (("both feet flat", (SHANK_VERTICAL, SHANK_VERTICAL)),
            ("right heel ahead, left ball behind", (LEADING_HEEL, TRAILING_BALL)))


def urdf_text(legs):
    """The URDF with MuJoCo's compiler options and only its first `legs` legs."""
    robot = ET.fromstring(URDF.read_text())
    dropped = [f"{s}_" for s in SIDES[legs:]]
    for el in list(robot):
        if el.tag in ("link", "joint") and el.get("name", "").startswith(tuple(dropped)):
            robot.remove(el)
    # fusestatic=false keeps each body as written; balanceinertia=false so that an inertia
    # violating the triangle inequality fails loudly instead of being altered.
    ext = ET.SubElement(robot, "mujoco")
    ET.SubElement(ext, "compiler", discardvisual="true", fusestatic="false",
                  balanceinertia="false")
    return ET.tostring(robot, encoding="unicode")


def hip_pitch_rad():
    """The pelvis tilt: the right hip origin's pitch (at this hip flexion the thigh hangs
    vertical)."""
    for j in ET.fromstring(URDF.read_text()).iter("joint"):
        if j.get("name") == "right_hip":
            return float(j.find("origin").get("rpy").split()[1])
    sys.exit(f"{URDF}: no joint right_hip")


def build(body_mass_kg, legs):
    """The URDF as MuJoCo reads it, plus floor, patient mass, servos and orthoses. Returns
    the model, the mass the belt and harness carry and the mass put on the pelvis (kg)."""
    spec = mujoco.MjSpec.from_string(urdf_text(legs))
    spec.option.gravity = [0.0, 0.0, -G]
    spec.option.timestep = DT
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # kv implicit: stable
    # Frictionless (condim 1): at rest a sticking contact (MuJoCo's friction cone, pma-leg's
    # elasto-plastic friction) holds whatever shear the settling left, which the statics do
    # not fix; the rapier test sets pma-leg's friction to 0 too.
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                            size=[2.0, 2.0, 0.1], contype=0, conaffinity=1, condim=1)
    for g in spec.geoms:
        if g.name == "floor":
            continue
        # Only the feet's spheres are collision geometry in the URDF.
        side = g.parent.name.removesuffix("_foot")
        g.name = f"{side}_{'heel' if g.pos[0] < 0 else 'ball'}"
        g.contype, g.conaffinity, g.condim = 1, 0, 1
        g.solref, g.solimp = STIFF_SOLREF, STIFF_SOLIMP
    carried = body_mass_kg * (1.0 - legs * LEG_MASS_FRACTION)
    spec.body("pelvis").mass += carried
    angle = (lambda deg: deg) if spec.compiler.degree else math.radians
    for j in spec.joints:
        # Statics only: hips and knees free of their stops (a stop force would take part of
        # the holding torque) and of the URDF's effort 200 N m (MuJoCo's actuatorfrcrange,
        # which would clip the servo).
        j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
        j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if j.name.endswith("_ankle"):
            # The orthosis: a spring about its rest, damped, within its stops.
            j.stiffness = [ANKLE["stiffness_nm_per_rad"], 0.0, 0.0]
            j.springref = angle(ANKLE["rest_deg"])
            j.damping = [ANKLE["damping_nm_s_per_rad"], 0.0, 0.0]
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.range = [angle(a) for a in ANKLE["range_deg"]]
            j.solref_limit, j.solimp_limit = STIFF_SOLREF, STIFF_SOLIMP
        elif j.name == "pelvis_x":
            j.stiffness = [FORE_AFT_N_PER_M, 0.0, 0.0]
            j.damping = [FORE_AFT_N_S_PER_M, 0.0, 0.0]
    for side in SIDES[:legs]:
        for joint in ("hip", "knee"):
            name = f"{side}_{joint}"
            act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_position(kp=KP, kv=KV)
    model = spec.compile()
    for side in SIDES[:legs]:
        j = model.joint(f"{side}_ankle")
        want = [math.radians(ANKLE["rest_deg"])] + [math.radians(a) for a in ANKLE["range_deg"]]
        got = [model.qpos_spring[j.qposadr[0]], *model.jnt_range[j.id]]
        if not np.allclose(got, want, atol=1e-12):
            sys.exit(f"{URDF}: {j.name}: MuJoCo compiled rest and range {got} rad, not {want}")
    # What the belt and harness carry: the pelvis and everything below it (the fore-aft
    # trolley above it hangs on the frame).
    total = float(model.body_subtreemass[model.body("pelvis").id])
    return model, total, carried


def foot_contacts(m, d):
    """Per sphere: world force on the foot (N), contact point (m) and penetration (m)."""
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


def statics_torques(m, d, contacts, side):
    """A leg's holding torques (flexion and dorsiflexion positive) from the bodies' COMs and
    the contact forces by moment balance of the links below each joint: independent of the
    servo's output and of the orthosis."""
    tau = {}
    below = {"hip": ("thigh", "shank", "foot"), "knee": ("shank", "foot"), "ankle": ("foot",)}
    for joint, links in below.items():
        j = m.joint(f"{side}_{joint}").id
        anchor, axis = d.xanchor[j], d.xaxis[j]
        moment = np.zeros(3)
        for link in links:
            b = m.body(f"{side}_{link}").id
            moment += np.cross(d.xipos[b] - anchor, [0, 0, -m.body_mass[b] * G])
        for name, (f, p, _) in contacts.items():
            if name.startswith(side + "_"):
                moment += np.cross(p - anchor, f)
        tau[joint] = -float(axis @ moment)  # what the joint must apply against them
    return tau


def limit_torque(m, d, joint):
    """The stop's torque on `joint` (N m, in its positive sense; 0 off its stops)."""
    j = m.joint(joint)
    dof = j.dofadr[0]
    efc_j = d.efc_J.reshape(d.nefc, m.nv) if d.nefc else np.zeros((0, m.nv))
    return float(sum(efc_j[i, dof] * d.efc_force[i] for i in range(d.nefc)
                     if d.efc_type[i] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
                     and d.efc_id[i] == j.id))


def settle(m, poses, bws, total):
    """Static equilibrium at `poses` (per leg, hip and knee in rad): returns the data and
    the simulated time it took (s)."""
    d = mujoco.MjData(m)
    legs = len(poses)
    adr = [m.joint(f"{s}_{j}").qposadr[0] for s in SIDES[:legs] for j in ("hip", "knee")]
    target = np.array([q for pose in poses for q in pose])
    d.qpos[adr] = target
    for s in SIDES[:legs]:
        d.qpos[m.joint(f"{s}_ankle").qposadr[0]] = math.radians(ANKLE["rest_deg"])
    # Start with the lowest sphere just touching the belt.
    mujoco.mj_kinematics(m, d)
    spheres = [m.geom(f"{s}_{p}").id for s in SIDES[:legs] for p in ("heel", "ball")]
    slide = m.joint("pelvis_z")
    d.qpos[slide.qposadr[0]] = -min(d.geom_xpos[g][2] - m.geom_size[g][0] for g in spheres)
    d.ctrl[:] = target  # actuators in the order added: the legs' hip and knee
    d.xfrc_applied[m.body("pelvis").id, 2] = bws * total * G  # constant-force harness
    weight = (1.0 - bws) * total * G
    m.dof_damping[slide.dofadr[0]] = SLIDE_DAMPING_N_S_PER_M
    steps = 0
    while steps * DT < MAX_SECONDS:
        mujoco.mj_step(m, d, nstep=STEPS_PER_CORRECTION)
        steps += STEPS_PER_CORRECTION
        pose_err = target - d.qpos[adr]
        # The servo sags by torque/kp; shifting its set-point by the sag holds the pose.
        d.ctrl[:] += pose_err
        if steps % 2000 == 0:
            mujoco.mj_forward(m, d)
            fz = sum(f[2] for f, _, _ in foot_contacts(m, d).values())
            if (np.abs(pose_err).max() < 1e-10 and np.abs(d.qvel).max() < 1e-8
                    and abs(fz - weight) < 1e-7 * weight):
                break
    mujoco.mj_forward(m, d)
    return d, steps * DT


def case(m, total, carried, body_mass_kg, name, poses_deg, bws, tilt):
    poses = [(tilt + math.radians(t), math.radians(k)) for t, k in poses_deg]
    d, settle_s = settle(m, poses, bws, total)
    contacts = foot_contacts(m, d)
    weight = (1.0 - bws) * total * G
    feet = []
    for side, (thigh_deg, knee_deg), (hip, knee) in zip(SIDES, poses_deg, poses):
        fz = {p: float(contacts[f"{side}_{p}"][0][2]) if f"{side}_{p}" in contacts else 0.0
              for p in ("heel", "ball")}
        vertical = fz["heel"] + fz["ball"]
        ankle = m.joint(f"{side}_ankle")
        hand = statics_torques(m, d, contacts, side)
        feet.append({
            "side": side, "thigh_deg": thigh_deg, "hip_deg": math.degrees(hip),
            "knee_deg": knee_deg,
            "vertical_n": vertical, "heel_vertical_n": fz["heel"], "ball_vertical_n": fz["ball"],
            "heel_share": fz["heel"] / vertical if vertical > 0 else None,
            "horizontal_n": float(sum(f[0] for n, (f, _, _) in contacts.items()
                                      if n.startswith(side + "_"))),
            "hip_torque_nm": float(d.actuator(f"{side}_hip").force[0]),
            "knee_torque_nm": float(d.actuator(f"{side}_knee").force[0]),
            "hip_torque_statics_nm": hand["hip"], "knee_torque_statics_nm": hand["knee"],
            "ankle_deg": math.degrees(d.qpos[ankle.qposadr[0]]),
            "ankle_spring_nm": float(d.qfrc_spring[ankle.dofadr[0]]),
            "ankle_stop_nm": limit_torque(m, d, ankle.name),
            "ankle_torque_statics_nm": hand["ankle"],
            "penetration_m": {n.split("_")[1]: float(c[2]) for n, c in contacts.items()
                              if n.startswith(side + "_")},
            "pose_error_rad": float(np.abs(np.array([hip, knee]) - d.qpos[
                [m.joint(f"{side}_{j}").qposadr[0] for j in ("hip", "knee")]]).max()),
        })
    total_fz = sum(f["vertical_n"] for f in feet)
    return {
        "name": name, "legs": len(poses), "bws_fraction": bws, "body_mass_kg": body_mass_kg,
        "carried_on_pelvis_kg": carried, "total_mass_kg": total,
        "expected_vertical_n": weight, "vertical_n": total_fz,
        "vertical_error_pct": 100.0 * (total_fz - weight) / weight,
        "feet": feet,
        "pelvis_z_m": float(d.qpos[m.joint("pelvis_z").qposadr[0]]),
        "max_abs_qvel": float(np.abs(d.qvel).max()),
        "settle_s": settle_s,
    }


def all_cases(body_mass_kg):
    tilt = hip_pitch_rad()
    rows = []
    for legs, postures in ((1, ONE_LEG), (2, TWO_LEGS)):
        m, total, carried = build(body_mass_kg, legs)
        for bws in BWS_FRACTIONS:
            for name, poses in postures:
                rows.append(case(m, total, carried, body_mass_kg, name, poses, bws, tilt))
    return rows


CHECKED = ("vertical_n", "heel_vertical_n", "ball_vertical_n", "hip_torque_nm",
           "knee_torque_nm", "ankle_spring_nm")


def load_cases(path):
    """The cases of an earlier --json output; exits with one line if it cannot be read."""
    try:
        cases = json.loads(pathlib.Path(path).read_text())["cases"]
        [(c["name"], c["legs"], c["bws_fraction"], [f[k] for f in c["feet"] for k in CHECKED])
         for c in cases]
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"{path}: not a stance.py --json output ({type(e).__name__}: {e})")
    return cases


def check(rows, old, path):
    """Compares `rows` with `old` (read from `path`); a message (exit 1) if they moved."""
    if [(c["name"], c["legs"], c["bws_fraction"]) for c in old] != \
            [(c["name"], c["legs"], c["bws_fraction"]) for c in rows]:
        return f"{path}: other cases than the script's: regenerate it with --json"
    for a, b in zip(old, rows):
        for fa, fb in zip(a["feet"], b["feet"]):
            for k in CHECKED:
                scale = max(abs(a["expected_vertical_n"]) * 0.01, abs(fa[k]))
                if abs(fa[k] - fb[k]) > 1e-3 * scale:
                    return (f"{path}: {b['name']}, {b['legs']} leg(s), bws {b['bws_fraction']}, "
                            f"{fb['side']}: {k} {fa[k]} there, {fb[k]} now: regenerate it")
    print(f"{path}: the {len(rows)} cases agree within 0.1 %")
    return 0


def table(rows, body_mass_kg):
    print(f"MuJoCo {mujoco.__version__}, {URDF.name}, body mass {body_mass_kg} kg, g {G}")
    print(f"{'case':<44} {'bws':>4} {'(1-b)mg N':>9} {'foot':>5} {'Fz N':>7} {'heel%':>6} "
          f"{'hip Nm':>8} {'knee Nm':>8} {'ankle deg':>9} {'spring Nm':>9} {'stop Nm':>8} "
          f"{'statics hip/knee/ankle Nm':>26}")
    for r in rows:
        for i, f in enumerate(r["feet"]):
            label = f"{r['name']} ({r['legs']} leg{'s' if r['legs'] > 1 else ''})"
            head = (f"{label:<44} {r['bws_fraction']:4.1f} {r['expected_vertical_n']:9.2f}"
                    if i == 0 else " " * 59)
            heel = 100 * f["heel_share"] if f["heel_share"] is not None else float("nan")
            print(f"{head} {f['side']:>5} {f['vertical_n']:7.2f} {heel:6.2f} "
                  f"{f['hip_torque_nm']:8.3f} {f['knee_torque_nm']:8.3f} {f['ankle_deg']:9.2f} "
                  f"{f['ankle_spring_nm']:9.2f} {f['ankle_stop_nm']:8.2f} "
                  f"{f['hip_torque_statics_nm']:8.3f} {f['knee_torque_statics_nm']:8.3f} "
                  f"{f['ankle_torque_statics_nm']:8.3f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--body-mass-kg", type=float, default=75.0,
                    help="the patient's mass (kg, 15..200 as pma-leg's [treadmill]; default 75)")
    out = ap.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="JSON on stdout instead of a table")
    out.add_argument("--check", metavar="FILE",
                     help="compare with an earlier --json output (CI: tools/mujoco/stance.json, "
                          "which crates/pma-leg/tests/mujoco_stance.rs reads); exit 1 if a "
                          "force or torque moved by more than 0.1 %%")
    args = ap.parse_args()
    if not 15.0 <= args.body_mass_kg <= 200.0:
        sys.exit(f"--body-mass-kg {args.body_mass_kg}: must be 15..200 kg (a patient's mass, "
                 "as pma-leg's treadmill.body_mass_kg)")
    old = load_cases(args.check) if args.check else None
    rows = all_cases(args.body_mass_kg)
    unsettled = [f"{r['name']} ({r['legs']} leg(s), bws {r['bws_fraction']})" for r in rows
                 if r["settle_s"] >= MAX_SECONDS or abs(r["vertical_error_pct"]) > 1e-3]
    if unsettled:
        sys.exit(f"not at rest after {MAX_SECONDS} s: {', '.join(unsettled)}")
    if args.check:
        sys.exit(check(rows, old, args.check))
    if args.json:
        json.dump({"mujoco": mujoco.__version__, "urdf": str(URDF.relative_to(ROOT)),
                   "gravity": G, "ankle": ANKLE, "cases": rows}, sys.stdout, indent=1)
        print()
    else:
        table(rows, args.body_mass_kg)


if __name__ == "__main__":
    main()
