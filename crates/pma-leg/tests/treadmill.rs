//! Physics checks of the treadmill: the foot's compliant contact on the belt, the pelvis on
//! body-weight support, the virtual other leg, and the servo-driven gait on the belt
//! (issue 19). `cargo test -p pma-leg --test treadmill -- --nocapture` prints the figures
//! docs/treadmill.md quotes.
use pma_leg::config::{JointSettings, EMBEDDED_FOOT_URDF};
use pma_leg::demand::stride_demand;
use pma_leg::ground::{ContactParams, Contralateral, TreadmillSettings};
use pma_leg::{Leg, LegSim, Scenario};

const PERIOD_S: f64 = 1e-3;

/// The hip's flexion at which the thigh hangs vertical: the URDF's pelvis tilt (rad).
const UPRIGHT_HIP_RAD: f64 = 0.1929;

/// One leg on a belt at `speed` with `bws` support and no other leg.
fn settings(speed: f64, bws: f64) -> TreadmillSettings {
    TreadmillSettings {
        speed_m_per_s: Some(speed),
        contralateral: Contralateral::None,
        ..TreadmillSettings::new(bws, 75.0)
    }
}

fn leg(t: &TreadmillSettings, substeps: u32) -> Leg {
    let j = JointSettings {
        damping_nm_s_per_rad: 0.5,
        friction_nm: 0.0,
    };
    Leg::on_treadmill(
        EMBEDDED_FOOT_URDF,
        "exo_leg_foot.urdf",
        [j, j],
        PERIOD_S,
        substeps,
        t,
    )
    .unwrap()
}

/// Stiff joint servos standing in for the muscles that hold the posture `q0`.
fn hold(l: &Leg, q0: [f64; 2]) -> [f64; 2] {
    let (q, qd) = (l.angles(), l.velocities());
    [0, 1].map(|k| -3000.0 * (q[k] - q0[k]) - 60.0 * qd[k])
}

/// Thigh 5.7 deg forward, knee 5.7 deg flexed: the shank vertical and the foot flat.
const FLAT_FOOT: [f64; 2] = [UPRIGHT_HIP_RAD + 0.1, 0.1];

struct Stance {
    grf_n: f64,
    expected_n: f64,
    penetration_m: f64,
    pelvis_drift_m: f64,
}

/// Stands `seconds` at the flat-foot posture on a stopped belt; averages the last second.
fn stand(t: &TreadmillSettings, substeps: u32, seconds: f64) -> Stance {
    let mut l = leg(t, substeps);
    l.set_state(FLAT_FOOT, [0.0, 0.0]);
    l.rest_on_belt();
    let periods = (seconds / PERIOD_S) as usize;
    let last = (1.0 / PERIOD_S) as usize;
    let (mut sum, mut deepest) = (0.0, 0.0f64);
    let mut z = Vec::new();
    for k in 0..periods {
        l.step(|l, _| hold(l, FLAT_FOOT));
        let r = l.ground_reaction().unwrap();
        assert!(r.vertical_n.is_finite(), "period {k}");
        if k >= periods - last {
            sum += r.vertical_n;
            deepest = deepest.max(r.penetration_m);
            z.push(l.pelvis_height_m().unwrap());
        }
    }
    let (lo, hi) = z
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    Stance {
        grf_n: sum / last as f64,
        expected_n: l.ground().unwrap().unsupported_weight_n(),
        penetration_m: deepest,
        pelvis_drift_m: hi - lo,
    }
}

#[test]
fn the_patient_rides_on_the_pelvis_less_this_legs_segments() {
    let l = leg(&settings(0.0, 0.3), 1);
    let g = l.ground().unwrap();
    // 75 kg less thigh, leg and foot (Winter: 0.100, 0.0465, 0.0145) = 62.925 kg, plus the
    // URDF's pelvis frame 10, thigh 9.5, shank 4.9875 and foot 1.0875 kg; not the
    // fore-aft trolley, which the trainer's frame carries.
    assert!((g.carried_kg() - 62.925).abs() < 1e-9, "{}", g.carried_kg());
    assert!(
        (g.total_mass_kg() - 88.5).abs() < 1e-6,
        "{}",
        g.total_mass_kg()
    );
}

#[test]
fn standing_still_the_belt_carries_the_unsupported_weight() {
    for bws in [0.0, 0.3, 0.5] {
        let s = stand(&settings(0.0, bws), 1, 3.0);
        let err = (s.grf_n - s.expected_n) / s.expected_n;
        eprintln!(
            "bws {bws}: GRF {:.2} N vs (1 - bws) m g {:.2} N ({:+.3} %), penetration {:.2} mm, pelvis drift {:.4} mm over the last second",
            s.grf_n,
            s.expected_n,
            100.0 * err,
            s.penetration_m * 1e3,
            s.pelvis_drift_m * 1e3
        );
        assert!(
            err.abs() < 0.01,
            "bws {bws}: {} vs {}",
            s.grf_n,
            s.expected_n
        );
        // Hertz: never deeper than one sphere carrying the whole load (30.5 mm at 868 N;
        // two spheres sharing it equally sink 19.2 mm).
        let one_sphere =
            (s.expected_n / ContactParams::default().hertz_coefficient(0.03)).powf(2.0 / 3.0);
        assert!(s.penetration_m < one_sphere, "{} m", s.penetration_m);
        assert!(s.pelvis_drift_m < 1e-4, "{} m", s.pelvis_drift_m);
    }
}

#[test]
fn standing_on_both_legs_with_the_muscles_holding_the_belt_carries_the_weight_half_each() {
    // The whole treadmill scenario, belt stopped: the four muscles under APRC-NDO hold the
    // upright posture, the virtual other leg holds it too.
    let mut loaded = Scenario::load("gait_treadmill").unwrap();
    let t = loaded.scenario.treadmill.as_mut().unwrap();
    t.speed_m_per_s = Some(0.0);
    let mut sim = LegSim::new(&loaded).unwrap();
    sim.hold_pose([UPRIGHT_HIP_RAD, 0.0]);
    let expected = sim.leg().ground().unwrap().unsupported_weight_n();
    let mut sums = [0.0; 2];
    let mut n = 0;
    let mut keep = pma_loop::FnRecorder(
        |p: &pma_loop::Period<'_, pma_leg::SupervisedLeg, pma_leg::LegOutput>| {
            if p.t_s > 4.0 {
                let g = p.truth.ground.unwrap();
                sums[0] += g.vertical_n;
                sums[1] += g.contralateral_n;
                n += 1;
            }
        },
    );
    let report = sim.run(5.0, &mut keep).unwrap();
    let (ours, other) = (sums[0] / n as f64, sums[1] / n as f64);
    let err = (ours + other - expected) / expected;
    eprintln!(
        "standing on both legs, muscles holding: this foot {ours:.1} N + the other leg {other:.1} N = {:.1} N vs (1 - bws) m g {expected:.1} N ({:+.3} %); hip error {:.3} deg, knee {:.3} deg",
        ours + other,
        100.0 * err,
        report.joints["hip"].max_deg,
        report.joints["knee"].max_deg
    );
    assert!(err.abs() < 0.01, "{ours} + {other} vs {expected}");
    assert!(
        (ours - other).abs() < 0.05 * expected,
        "the two legs stand alike: {ours} vs {other}"
    );
}

struct Landing {
    peak_n: f64,
    loading_rate_n_s: f64,
    penetration_m: f64,
    settled_grf_n: f64,
    expected_n: f64,
}

/// Drops the leg from 3 cm, joints held near straight, and measures the landing.
fn land(substeps: u32) -> Landing {
    let t = settings(0.0, 0.3);
    let mut l = leg(&t, substeps);
    l.set_state(FLAT_FOOT, [0.0, 0.0]);
    l.rest_on_belt();
    l.lift_pelvis(0.03 + 0.02);
    let (mut peak, mut t_first, mut t_peak, mut deepest, mut settled) =
        (0.0f64, None, 0.0, 0.0f64, 0.0);
    let periods = 2000;
    for k in 0..periods {
        l.step(|l, _| hold(l, FLAT_FOOT));
        let r = l.ground_reaction().unwrap();
        let t_s = (k + 1) as f64 * PERIOD_S;
        if r.vertical_n > 0.0 && t_first.is_none() {
            t_first = Some(t_s);
        }
        if r.vertical_n > peak {
            (peak, t_peak) = (r.vertical_n, t_s);
        }
        deepest = deepest.max(r.penetration_m);
        if k >= periods - 500 {
            settled += r.vertical_n / 500.0;
        }
    }
    let t_first = t_first.expect("the foot lands");
    Landing {
        peak_n: peak,
        loading_rate_n_s: peak / (t_peak - t_first + PERIOD_S),
        penetration_m: deepest,
        settled_grf_n: settled,
        expected_n: l.ground().unwrap().unsupported_weight_n(),
    }
}

#[test]
fn a_landing_converges_under_substep_refinement() {
    let runs: Vec<(u32, Landing)> = [1, 2, 4, 8].map(|n| (n, land(n))).into_iter().collect();
    for (n, r) in &runs {
        eprintln!(
            "3 cm drop, {n} substep(s): peak GRF {:.1} N, mean loading rate {:.0} N/s, deepest {:.2} mm, settled {:.2} N (expected {:.2} N)",
            r.peak_n,
            r.loading_rate_n_s,
            r.penetration_m * 1e3,
            r.settled_grf_n,
            r.expected_n
        );
    }
    let fine = &runs[3].1;
    let errors: Vec<f64> = runs[..3]
        .iter()
        .map(|(_, r)| (r.peak_n - fine.peak_n).abs() / fine.peak_n)
        .collect();
    eprintln!("3 cm drop: peak GRF off the 8-substep one at 1, 2, 4 substeps: {errors:?}");
    assert!(
        errors[0] > errors[1] && errors[1] > errors[2],
        "no convergence: {errors:?}"
    );
    for (n, r) in &runs {
        assert!(
            (r.settled_grf_n - r.expected_n).abs() < 0.01 * r.expected_n,
            "{n} substeps: settled {} vs {}",
            r.settled_grf_n,
            r.expected_n
        );
    }
    assert!(
        fine.peak_n > fine.expected_n,
        "a landing overshoots the static load"
    );
}

#[test]
fn a_running_belt_drags_a_held_foot_backwards_at_the_sliding_limit() {
    // The pelvis held fore-aft (a stiff harness) and the servos holding the posture: the
    // foot cannot follow the belt, so it slides at (mu + mu_v v) F_n.
    let t = TreadmillSettings {
        pelvis_fore_aft_n_per_m: 1e5,
        pelvis_fore_aft_damping_n_s_per_m: 6000.0,
        ..settings(0.6, 0.3)
    };
    let mut l = leg(&t, 1);
    l.set_state(FLAT_FOOT, [0.0, 0.0]);
    l.rest_on_belt();
    let mut last = None;
    for _ in 0..1500 {
        l.step(|l, _| hold(l, FLAT_FOOT));
        last = l.ground_reaction();
    }
    let r = last.unwrap();
    let expected = -(0.8 + 0.5 * r.slip_m_s) * r.vertical_n;
    eprintln!(
        "belt 0.6 m/s, foot held: slip {:.3} m/s, fore-aft {:.1} N vs -(mu + mu_v v) F_n {:.1} N, vertical {:.1} N",
        r.slip_m_s, r.fore_aft_n, expected, r.vertical_n
    );
    assert!(r.slip_m_s > 0.5 && r.slip_m_s < 0.7, "{r:?}");
    assert!(
        (r.fore_aft_n - expected).abs() < 0.02 * expected.abs(),
        "{r:?}"
    );
}

#[test]
fn a_stopped_belt_holds_a_pushed_foot_still_below_the_friction_limit() {
    // Pushing the held foot forward with a small hip torque: the sole shears (Mindlin's
    // stiffness) but does not slide, so the foot creeps by well under a millimetre.
    let t = settings(0.0, 0.3);
    let mut l = leg(&t, 1);
    l.set_state(FLAT_FOOT, [0.0, 0.0]);
    l.rest_on_belt();
    let x0 = l.point_in_world("shank", [0.0, 0.0, -0.4305]).unwrap()[0];
    let mut worst = 0.0f64;
    for k in 0..2000 {
        let push = if k > 500 { 20.0 } else { 0.0 };
        l.step(|l, _| {
            let h = hold(l, FLAT_FOOT);
            [h[0] + push, h[1]]
        });
        if k > 1000 {
            let x = l.point_in_world("shank", [0.0, 0.0, -0.4305]).unwrap()[0];
            worst = worst.max((x - x0).abs());
        }
    }
    let r = l.ground_reaction().unwrap();
    eprintln!(
        "stopped belt, 20 N m pushing: the ankle moved {:.3} mm, fore-aft GRF {:.1} N of a {:.1} N limit, slip {:.2e} m/s",
        worst * 1e3,
        r.fore_aft_n,
        0.8 * r.vertical_n,
        r.slip_m_s
    );
    assert!(r.fore_aft_n.abs() < 0.8 * r.vertical_n);
    assert!(worst < 1e-3, "{worst} m");
    assert!(r.slip_m_s < 1e-3, "{r:?}");
}

#[test]
fn the_other_legs_spheres_are_where_rapier_puts_this_legs() {
    // The virtual other leg is this leg's sagittal chain evaluated at other angles: at
    // the same angles, its spheres are where the multibody has them.
    let mut l = leg(&settings(0.0, 0.3), 1);
    for q in [[0.0, 0.0], [0.5, 0.9], [-0.2, 0.3], [0.7, 0.1]] {
        l.set_state(q, [0.0, 0.0]);
        let g = l.ground().unwrap();
        let pelvis = l
            .link_poses()
            .into_iter()
            .find(|p| p.0 == "pelvis")
            .unwrap()
            .1;
        for (i, s) in g.spheres().iter().enumerate() {
            let rapier = l.point_in_world(g.foot_link_name(), s.center_m).unwrap();
            let chain = g.chain().sphere_centre(i, q);
            let (dx, dz) = (
                pelvis[0] + chain[0] - rapier[0],
                pelvis[2] + chain[1] - rapier[2],
            );
            assert!(
                dx.abs() < 1e-5 && dz.abs() < 1e-5,
                "q {q:?}, sphere {i}: {dx} {dz}"
            );
        }
    }
}

#[test]
fn over_whole_strides_the_belt_carries_the_unsupported_weight() {
    // Impulse balance: whatever the gait does, the pelvis ends each stride where it began,
    // so this foot and the other leg carry (1 - bws) m g on average.
    let loaded = Scenario::load("gait_treadmill").unwrap();
    let d = stride_demand(&loaded, 3).unwrap();
    let t = d.treadmill.unwrap();
    let err = (t.mean_belt_load_bw - t.expected_belt_load_bw) / t.expected_belt_load_bw;
    eprintln!(
        "servo-driven gait_treadmill, 3 strides: this foot {:.4} + the other leg {:.4} = {:.4} BW vs (1 - bws) {:.4} BW ({:+.3} %); stance {:.3} (reference {:.3}), loading peak {:.3} BW, loading rate {:.2} BW/s, slip {:.1} mm per stride ({:.3} m/s in stance, belt {:.3} m/s), pelvis excursion {:.1} mm, deepest {:.1} mm; servo error up to {:.2} / {:.2} deg",
        t.mean_grf_bw,
        t.mean_other_leg_bw,
        t.mean_belt_load_bw,
        t.expected_belt_load_bw,
        100.0 * err,
        t.stance_fraction.mean,
        t.reference_stance_fraction,
        t.peak_grf_bw.mean,
        t.loading_rate_bw_s.mean,
        1e3 * t.slip_per_stride_m.mean,
        t.mean_stance_slip_m_s,
        t.belt_speed_m_s,
        1e3 * t.pelvis_excursion_m,
        t.max_penetration_mm,
        d.max_error_deg[0],
        d.max_error_deg[1]
    );
    assert_eq!(t.strides, 3, "{t:?}");
    assert!(err.abs() < 0.005, "{t:?}");
    // The two legs share it alike.
    assert!(
        (t.mean_grf_bw - t.mean_other_leg_bw).abs() < 0.05 * t.mean_belt_load_bw,
        "{t:?}"
    );
    // At the reference's own speed the stance foot slides at under a tenth of the belt's.
    assert!(t.mean_stance_slip_m_s < 0.1 * t.belt_speed_m_s, "{t:?}");
}

#[test]
fn the_gait_on_the_belt_converges_under_substep_refinement() {
    // The scenario runs one substep per 1 ms period: the servo-driven gait's ground
    // reaction at 1, 2 and 4 substeps.
    let mut figures = Vec::new();
    for n in [1, 2, 4] {
        let mut loaded = Scenario::load("gait_treadmill").unwrap();
        loaded.scenario.physics_substeps = n;
        let t = stride_demand(&loaded, 2).unwrap().treadmill.unwrap();
        eprintln!(
            "gait on the belt, {n} substep(s): loading peak {:.4} BW, loading rate {:.3} BW/s, stance {:.4}, slip {:.2} mm per stride",
            t.peak_grf_bw.mean,
            t.loading_rate_bw_s.mean,
            t.stance_fraction.mean,
            1e3 * t.slip_per_stride_m.mean
        );
        figures.push((t.peak_grf_bw.mean, t.loading_rate_bw_s.mean));
    }
    let fine = figures[2];
    for (k, f) in figures[..2].iter().enumerate() {
        let peak = (f.0 - fine.0).abs() / fine.0;
        let rate = (f.1 - fine.1).abs() / fine.1;
        assert!(peak < 0.01 && rate < 0.02, "{k}: {f:?} vs {fine:?}");
    }
}

/// The error of building a treadmill leg from `urdf` with `t`.
fn treadmill_error(urdf: &str, t: &TreadmillSettings) -> String {
    let j = JointSettings {
        damping_nm_s_per_rad: 0.5,
        friction_nm: 0.0,
    };
    match Leg::on_treadmill(urdf, "x.urdf", [j, j], PERIOD_S, 2, t) {
        Ok(_) => panic!("built"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_treadmill_without_a_foot_or_slide_is_a_one_line_error() {
    let ok = settings(0.6, 0.3);
    let e = treadmill_error(pma_leg::config::EMBEDDED_URDF, &ok);
    assert!(e.contains("foot") && !e.contains('\n'), "{e}");
    let no_slide = EMBEDDED_FOOT_URDF.replace("type=\"prismatic\"", "type=\"fixed\"");
    let e = treadmill_error(&no_slide, &ok);
    assert!(e.contains("pelvis_z") && !e.contains('\n'), "{e}");
    let e = treadmill_error(EMBEDDED_FOOT_URDF, &settings(-1.0, 0.3));
    assert!(e.contains("treadmill.speed_m_per_s"), "{e}");
    let e = treadmill_error(EMBEDDED_FOOT_URDF, &settings(0.6, 1.5));
    assert!(e.contains("treadmill.bws_fraction"), "{e}");
}
