//! The trainer's static stances against MuJoCo's (issue 27): the same URDF
//! (`models/exo_trainer.urdf`, both legs, or the right one alone), the patient's mass on the
//! pelvis, body-weight support, hips and knees held by servos, each ankle on its orthosis,
//! a stopped frictionless belt; 18 stances (tools/mujoco/README.md). MuJoCo's figures come
//! from `python3 tools/mujoco/stance.py --json > tools/mujoco/stance.json` (MuJoCo 4.0.0
//! from PyPI); this test needs only the file, CI checks it is current.
//! `cargo test -p pma-leg --test mujoco_stance -- --nocapture` prints the figures.
//!
//! MuJoCo's contacts and stops are near-rigid there (a sphere sinks at most 0.7 mm), so
//! its figures are the rigid-contact statics. Where statics alone fix the belt's force on
//! each foot (one leg; two legs posed alike) it agrees within 0.1 % whatever the contact.
//! Elsewhere the orthoses' springs share the load and the ankles' angles follow the spheres'
//! sinkage, so the heel's share, a double support's split and the holding torques may move
//! by what the two contacts' different sinkage explains ([`allowance`]). The close
//! comparison runs pma-leg's Hertz contact at its stiffest (E = 1e9 N/m^2, sinking at most
//! 0.5 mm); the scenario's own (E = 2e6, sinking up to 31 mm) is compared too, except the
//! double support's split, which its sinkage decides.
use pma_leg::body::JointSettings;
use pma_leg::body::EMBEDDED_TRAINER_URDF;
use pma_leg::ground::{AnkleSettings, ContactParams, Contralateral, TreadmillSettings};
use pma_leg::{Exoskeleton, PerLeg};
use serde::Deserialize;

const PERIOD_S: f64 = 1e-3;
/// A foot resting on its orthosis's stop chatters against it at one substep (the ankle
/// bouncing 0.4 deg off the stop every 3 ms, the ball's force flipping between 0 and 1300 N):
/// the sampled belt load moves by up to 0.3 % and the holding torques by up to 0.8 N m
/// (ball only and crouched, 0 % BWS, the scenario's contact). At four substeps a crouched
/// hip is still 0.03 N m (0.12 %) off, at eight 0.006 N m; the stiffest contact needs more
/// than one too.
const SUBSTEPS: u32 = 8;
const SETTLE_S: f64 = 6.0;
/// Periods averaged at the end of the settling.
const AVERAGED: usize = 500;
/// The statically determinate figures' tolerance (and every figure's floor): 0.1 %.
const DETERMINATE: f64 = 1e-3;

#[derive(Debug, Deserialize)]
struct Stances {
    urdf: String,
    gravity: f64,
    ankle: OrthosisJson,
    cases: Vec<Case>,
}

#[derive(Debug, Deserialize)]
struct OrthosisJson {
    stiffness_nm_per_rad: f64,
    damping_nm_s_per_rad: f64,
    rest_deg: f64,
    range_deg: [f64; 2],
}

/// One MuJoCo stance.
#[derive(Debug, Deserialize)]
struct Case {
    name: String,
    legs: usize,
    bws_fraction: f64,
    body_mass_kg: f64,
    carried_on_pelvis_kg: f64,
    total_mass_kg: f64,
    expected_vertical_n: f64,
    vertical_n: f64,
    feet: Vec<Foot>,
}

/// One foot of a MuJoCo stance, and its leg's holding torques.
#[derive(Debug, Deserialize)]
struct Foot {
    side: String,
    hip_deg: f64,
    knee_deg: f64,
    vertical_n: f64,
    heel_vertical_n: f64,
    ball_vertical_n: f64,
    hip_torque_nm: f64,
    knee_torque_nm: f64,
    ankle_deg: f64,
    ankle_spring_nm: f64,
    penetration_m: Penetration,
}

/// A sphere out of contact is absent from MuJoCo's list.
#[derive(Debug, Default, Deserialize)]
struct Penetration {
    #[serde(default)]
    heel: f64,
    #[serde(default)]
    ball: f64,
}

impl Foot {
    fn pose_rad(&self) -> [f64; 2] {
        [self.hip_deg.to_radians(), self.knee_deg.to_radians()]
    }

    fn torque_nm(&self) -> [f64; 2] {
        [self.hip_torque_nm, self.knee_torque_nm]
    }

    fn sphere_n(&self) -> [f64; 2] {
        [self.heel_vertical_n, self.ball_vertical_n]
    }

    fn depth_m(&self) -> [f64; 2] {
        [self.penetration_m.heel, self.penetration_m.ball]
    }
}

impl Case {
    /// The belt's force on each foot follows from statics alone: one leg carries it all,
    /// two legs posed alike carry half each.
    fn determinate(&self) -> bool {
        self.legs == 1
            || self
                .feet
                .windows(2)
                .all(|w| w[0].pose_rad() == w[1].pose_rad())
    }
}

fn mujoco() -> Stances {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tools/mujoco/stance.json"
    );
    let text = std::fs::read_to_string(path).expect("tools/mujoco/stance.json");
    serde_json::from_str(&text).expect("tools/mujoco/stance.json as stance.py writes it")
}

/// One foot of the rapier trainer at rest, averaged over the last [`AVERAGED`] periods:
/// the belt's vertical force on each sphere (heel, ball), where it acts, the sinkage, the
/// leg's holding torques and the positions of its joints.
#[derive(Debug, Clone, Copy, Default)]
struct Standing {
    sphere_n: [f64; 2],
    depth_m: [f64; 2],
    /// Contact points, world X (m).
    point_x_m: [f64; 2],
    /// Hip, knee and ankle, world X (m).
    joint_x_m: [f64; 3],
    torque_nm: [f64; 2],
    ankle_deg: f64,
    orthosis_nm: f64,
    /// How far the spheres' centres lie below the ankle (m).
    centre_below_ankle_m: f64,
}

impl Standing {
    fn vertical_n(&self) -> f64 {
        self.sphere_n.iter().sum()
    }
}

/// The trainer of `c.legs` legs on a stopped belt with `contact` (frictionless), its
/// joints held at `c`'s pose by stiff servos with integral action (MuJoCo's corrected
/// set-points hold the pose exactly), after [`SETTLE_S`].
fn rapier(c: &Case, contact: ContactParams) -> Vec<Standing> {
    let t = TreadmillSettings {
        legs: c.legs,
        speed_m_per_s: Some(0.0),
        contralateral: Some(Contralateral::None),
        pelvis_fore_aft_n_per_m: 2000.0,
        pelvis_fore_aft_damping_n_s_per_m: 600.0,
        contact,
        ..TreadmillSettings::new(c.bws_fraction, c.body_mass_kg)
    };
    let j = JointSettings {
        damping_nm_s_per_rad: 0.0,
        friction_nm: 0.0,
    };
    let mut e = Exoskeleton::on_treadmill(
        EMBEDDED_TRAINER_URDF,
        "exo_trainer.urdf",
        [j, j],
        PERIOD_S,
        SUBSTEPS,
        &t,
    )
    .unwrap();
    let targets: Vec<[f64; 2]> = c.feet.iter().map(Foot::pose_rad).collect();
    for (leg, q) in targets.iter().enumerate() {
        e.set_state(leg, *q, [0.0, 0.0]);
    }
    e.rest_on_belt();
    let (kp, kd, ki) = (2.0e4, 150.0, 4.0e4);
    let h = PERIOD_S / f64::from(SUBSTEPS);
    let mut integral = vec![[0.0; 2]; c.legs];
    let mut applied = vec![[0.0; 2]; c.legs];
    let periods = (SETTLE_S / PERIOD_S) as usize;
    let mut sums = vec![Standing::default(); c.legs];
    for k in 0..periods {
        e.step(|e, _| {
            PerLeg::from_fn(c.legs, |leg| {
                let (q, qd) = (e.angles(leg), e.velocities(leg));
                applied[leg] = std::array::from_fn(|i| {
                    integral[leg][i] += (targets[leg][i] - q[i]) * h;
                    kp * (targets[leg][i] - q[i]) - kd * qd[i] + ki * integral[leg][i]
                });
                applied[leg]
            })
        });
        if k >= periods - AVERAGED {
            for (leg, sum) in sums.iter_mut().enumerate() {
                add(sum, &standing(&e, leg, applied[leg]), 1.0 / AVERAGED as f64);
            }
        }
    }
    sums
}

/// Leg `leg` of `e` now, the servos applying `torque_nm`.
fn standing(e: &Exoskeleton, leg: usize, torque_nm: [f64; 2]) -> Standing {
    let g = e.ground().unwrap();
    let foot = &g.feet()[leg];
    assert_eq!(foot.spheres.len(), 2, "a heel and a ball sphere");
    let x = |link: &str| e.point_in_world(link, [0.0; 3]).unwrap()[0];
    let names = e.leg(leg);
    let mut s = Standing {
        joint_x_m: ["thigh", "shank", "foot"].map(|l| x(&names.urdf_name(l))),
        torque_nm,
        ankle_deg: e.ankle(leg).unwrap().0.to_degrees(),
        orthosis_nm: e.ankle_torque_nm(leg),
        centre_below_ankle_m: foot
            .spheres
            .iter()
            .map(|s| -s.center_m[2])
            .fold(0.0, f64::max),
        ..Standing::default()
    };
    for (sphere, contact) in foot.spheres.iter().zip(g.sphere_contacts(leg)) {
        let i = usize::from(sphere.center_m[0] >= 0.0);
        let centre = e.point_in_world(&foot.link, sphere.center_m).unwrap();
        s.point_x_m[i] = centre[0];
        if let Some(c) = contact {
            s.sphere_n[i] = c.force_n[2];
            s.depth_m[i] = c.depth_m;
        }
    }
    s
}

/// `sum += w * s`, field by field.
fn add(sum: &mut Standing, s: &Standing, w: f64) {
    for i in 0..2 {
        sum.sphere_n[i] += w * s.sphere_n[i];
        sum.depth_m[i] += w * s.depth_m[i];
        sum.point_x_m[i] += w * s.point_x_m[i];
        sum.torque_nm[i] += w * s.torque_nm[i];
    }
    for i in 0..3 {
        sum.joint_x_m[i] += w * s.joint_x_m[i];
    }
    sum.ankle_deg += w * s.ankle_deg;
    sum.orthosis_nm += w * s.orthosis_nm;
    sum.centre_below_ankle_m += w * s.centre_below_ankle_m;
}

/// How far one foot's figures may lie from MuJoCo's: the belt's force on the foot and on
/// its heel (N), and the leg's holding torques (N m).
#[derive(Debug, Clone, Copy)]
struct Allowance {
    foot_n: f64,
    heel_n: f64,
    torque_nm: [f64; 2],
}

/// What the two contacts' different sinkage may move, foot by foot (rapier's geometry,
/// both models' sinkage), twice its first-order estimate (which leaves out the levers'
/// change with the ankles' angles); every figure within [`DETERMINATE`] on top:
/// - one foot on both spheres: the foot tilts by the difference of the heel's and the
///   ball's sinkage over the spheres' spacing `l`; the models' tilts differ by `dt`,
///   which changes the orthosis's torque by `k dt` and moves both contact points by
///   `h dt` (`h`: the spheres' centres below the ankle), so `(k + F h) dt / l` passes
///   from heel to ball, and the hip and knee torques move by `(k + F h) dt`;
/// - two feet on one sphere each (posed differently): the pelvis cannot pitch, so the
///   ankles' springs share the load; each passes load as a spring of `k / a^2` at its
///   contact (`a`: the contact's lever about the ankle), so a difference `dd` in the two
///   contacts' relative sinkage moves `k dd / (a1^2 + a2^2)` from one foot to the other,
///   and each joint's torque by that times its lever to the contact;
/// - otherwise (one leg on one sphere, or legs posed alike) statics alone decide.
fn allowance(c: &Case, ours: &[Standing], orthosis: &AnkleSettings) -> Vec<Allowance> {
    let k = orthosis.stiffness_nm_per_rad;
    let between = if c.determinate() {
        0.0
    } else {
        let loaded = |f: &Foot, s: &Standing| {
            let i = usize::from(f.ball_vertical_n > f.heel_vertical_n);
            (i, (s.point_x_m[i] - s.joint_x_m[2]).abs())
        };
        let (i0, a0) = loaded(&c.feet[0], &ours[0]);
        let (i1, a1) = loaded(&c.feet[1], &ours[1]);
        let relative = |d0: [f64; 2], d1: [f64; 2]| d0[i0] - d1[i1];
        let dd = (relative(ours[0].depth_m, ours[1].depth_m)
            - relative(c.feet[0].depth_m(), c.feet[1].depth_m()))
        .abs();
        k * dd / (a0 * a0 + a1 * a1)
    };
    c.feet
        .iter()
        .zip(ours)
        .map(|(f, s)| {
            let force = f.vertical_n;
            let loaded: Vec<usize> = (0..2).filter(|&i| f.sphere_n()[i] > 0.0).collect();
            let lever = |j: usize| {
                loaded
                    .iter()
                    .map(|&i| (s.point_x_m[i] - s.joint_x_m[j]).abs())
                    .fold(0.0, f64::max)
            };
            let floor = |j: usize| DETERMINATE * force * lever(j);
            if loaded.len() == 2 {
                let spacing = s.point_x_m[1] - s.point_x_m[0];
                let below = s.centre_below_ankle_m;
                let gap = |d: [f64; 2]| d[0] - d[1];
                let tilt = (gap(s.depth_m) - gap(f.depth_m())).abs() / spacing;
                let torque = 2.0 * (k + force * below) * tilt;
                Allowance {
                    foot_n: DETERMINATE * force + 2.0 * between,
                    heel_n: DETERMINATE * force + torque / spacing,
                    torque_nm: [0, 1].map(|j| floor(j) + torque),
                }
            } else {
                Allowance {
                    foot_n: DETERMINATE * force + 2.0 * between,
                    heel_n: DETERMINATE * force + 2.0 * between,
                    torque_nm: [0, 1].map(|j| floor(j) + 2.0 * between * lever(j)),
                }
            }
        })
        .collect()
}

fn print(c: &Case, ours: &[Standing], allowed: Option<&[Allowance]>, contact: &str) {
    for (i, (f, s)) in c.feet.iter().zip(ours).enumerate() {
        let pct = |a: f64, b: f64| 100.0 * (a - b) / b.abs().max(1e-9);
        let share = |heel: f64, total: f64| 100.0 * heel / total;
        eprintln!(
            "{contact}: {} ({} leg{}), bws {:.1}, {}: vertical {:.2} vs MuJoCo {:.2} N ({:+.3} %); heel {:.2} vs {:.2} %; hip {:.3} vs {:.3} N m ({:+.2} %), knee {:.3} vs {:.3} N m ({:+.2} %); ankle {:.2} vs {:.2} deg, orthosis {:.2} vs {:.2} N m; sinkage heel/ball {:.2}/{:.2} vs {:.2}/{:.2} mm{}",
            c.name,
            c.legs,
            if c.legs == 1 { "" } else { "s" },
            c.bws_fraction,
            f.side,
            s.vertical_n(),
            f.vertical_n,
            pct(s.vertical_n(), f.vertical_n),
            share(s.sphere_n[0], s.vertical_n()),
            share(f.heel_vertical_n, f.vertical_n),
            s.torque_nm[0],
            f.hip_torque_nm,
            pct(s.torque_nm[0], f.hip_torque_nm),
            s.torque_nm[1],
            f.knee_torque_nm,
            pct(s.torque_nm[1], f.knee_torque_nm),
            s.ankle_deg,
            f.ankle_deg,
            s.orthosis_nm,
            f.ankle_spring_nm,
            1e3 * s.depth_m[0],
            1e3 * s.depth_m[1],
            1e3 * f.penetration_m.heel,
            1e3 * f.penetration_m.ball,
            allowed.map_or(String::new(), |a| format!(
                "; allowed {:.2} N (foot), {:.2} N (heel), {:.3} / {:.3} N m",
                a[i].foot_n, a[i].heel_n, a[i].torque_nm[0], a[i].torque_nm[1]
            )),
        );
    }
}

/// Frictionless: at rest a sticking contact holds whatever shear the settling left, which
/// the statics do not fix (MuJoCo's floor is frictionless too).
fn frictionless(stiffness_n_per_m2: f64) -> ContactParams {
    ContactParams {
        stiffness_n_per_m2,
        friction: 0.0,
        viscous_friction_s_per_m: 0.0,
        ..ContactParams::default()
    }
}

/// The whole belt load within 0.1 % of MuJoCo's and of `(1 - bws) m g`.
fn assert_belt_load(c: &Case, ours: &[Standing]) {
    let total: f64 = ours.iter().map(Standing::vertical_n).sum();
    for (theirs, what) in [
        (c.vertical_n, "MuJoCo's"),
        (c.expected_vertical_n, "(1 - bws) m g"),
    ] {
        assert!(
            (total - theirs).abs() < DETERMINATE * theirs,
            "{} ({} legs), bws {}: belt load {total} vs {what} {theirs}",
            c.name,
            c.legs,
            c.bws_fraction
        );
    }
}

#[test]
fn mujoco_modelled_the_same_trainer() {
    let m = mujoco();
    assert!(m.urdf.ends_with("models/exo_trainer.urdf"), "{}", m.urdf);
    assert_eq!(m.gravity, pma_model::GRAVITY_M_S2);
    let a = AnkleSettings::default();
    assert_eq!(
        [
            m.ankle.stiffness_nm_per_rad,
            m.ankle.damping_nm_s_per_rad,
            m.ankle.rest_deg
        ],
        [a.stiffness_nm_per_rad, a.damping_nm_s_per_rad, a.rest_deg]
    );
    assert_eq!(m.ankle.range_deg, a.range_deg);
    let sides: Vec<&str> = pma_leg::SIDES.to_vec();
    for c in &m.cases {
        let t = TreadmillSettings {
            legs: c.legs,
            contralateral: Some(Contralateral::None),
            ..TreadmillSettings::new(c.bws_fraction, c.body_mass_kg)
        };
        let j = JointSettings {
            damping_nm_s_per_rad: 0.0,
            friction_nm: 0.0,
        };
        let e = Exoskeleton::on_treadmill(
            EMBEDDED_TRAINER_URDF,
            "exo_trainer.urdf",
            [j, j],
            PERIOD_S,
            1,
            &t,
        )
        .unwrap();
        let g = e.ground().unwrap();
        assert!(
            (g.carried_kg() - c.carried_on_pelvis_kg).abs() < 1e-9,
            "{c:?}"
        );
        assert!((g.total_mass_kg() - c.total_mass_kg).abs() < 1e-9, "{c:?}");
        assert!(
            (g.unsupported_weight_n() - c.expected_vertical_n).abs() < 1e-9,
            "{c:?}"
        );
        let theirs: Vec<&str> = c.feet.iter().map(|f| f.side.as_str()).collect();
        assert_eq!(theirs, sides[..c.legs], "{}", c.name);
    }
}

/// Each foot's belt force, its heel's share (a sphere MuJoCo lifts off the belt is off it
/// here too) and its leg's holding torques within `allowed` of MuJoCo's.
fn assert_feet(c: &Case, ours: &[Standing], allowed: &[Allowance]) {
    for ((f, s), a) in c.feet.iter().zip(ours).zip(allowed) {
        let at = format!(
            "{} ({} legs), bws {}, {}",
            c.name, c.legs, c.bws_fraction, f.side
        );
        assert!(
            (s.vertical_n() - f.vertical_n).abs() < a.foot_n,
            "{at}: foot {} vs {} N (allowed {})",
            s.vertical_n(),
            f.vertical_n,
            a.foot_n
        );
        assert!(
            (s.sphere_n[0] - f.heel_vertical_n).abs() < a.heel_n,
            "{at}: heel {} vs {} N (allowed {})",
            s.sphere_n[0],
            f.heel_vertical_n,
            a.heel_n
        );
        for i in 0..2 {
            assert_eq!(s.sphere_n[i] == 0.0, f.sphere_n()[i] == 0.0, "{at}: {s:?}");
        }
        for (j, (ours, theirs)) in s.torque_nm.iter().zip(f.torque_nm()).enumerate() {
            assert!(
                (ours - theirs).abs() < a.torque_nm[j],
                "{at}: joint {j} {ours} vs {theirs} N m (allowed {})",
                a.torque_nm[j]
            );
        }
    }
}

#[test]
fn static_stances_on_a_stiff_contact_agree_with_mujoco() {
    let m = mujoco();
    assert_eq!(m.cases.len(), 18);
    let orthosis = AnkleSettings::default();
    for c in &m.cases {
        let ours = rapier(c, frictionless(1e9));
        let allowed = allowance(c, &ours, &orthosis);
        print(c, &ours, Some(&allowed), "stiff contact");
        assert_belt_load(c, &ours);
        assert_feet(c, &ours, &allowed);
    }
}

#[test]
fn on_the_scenarios_contact_the_stances_agree_with_mujoco_within_its_sinkage() {
    let m = mujoco();
    let orthosis = AnkleSettings::default();
    for c in &m.cases {
        let ours = rapier(c, frictionless(ContactParams::default().stiffness_n_per_m2));
        assert_belt_load(c, &ours);
        if c.determinate() {
            let allowed = allowance(c, &ours, &orthosis);
            print(c, &ours, Some(&allowed), "scenario's contact");
            assert_feet(c, &ours, &allowed);
        } else {
            // Double support: the leading heel sinks 15-23 mm more than MuJoCo's, the
            // trailing ball 9-16 mm, so the pelvis sits lower and the trailing ankle
            // dorsiflexes 2.5-4.3 deg further (onto its stop at 0 and 30 % BWS): the split
            // between the feet is the contacts' and the first-order allowance no longer
            // bounds it (the trailing foot carries 140-323 N instead of 89-133 N). The belt
            // load is still (1 - bws) m g.
            print(c, &ours, None, "scenario's contact");
        }
    }
}
