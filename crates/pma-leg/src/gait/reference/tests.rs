//! Tests of `reference.rs`.
use super::*;

fn deg(r: f64) -> f64 {
    r.to_degrees()
}

#[test]
fn sampling_a_cycle_interpolates_and_wraps() {
    let c = [0.0, 10.0, 20.0];
    assert_eq!(sample_cycle(&c, 0.25), 5.0);
    assert_eq!(sample_cycle(&c, 1.0), 0.0);
    assert_eq!(sample_cycle(&c, -0.25), 15.0);
    assert_eq!(sample_cycle(&[4.0], 0.3), 4.0);
}

#[test]
fn the_adults_loading_response_is_the_curves_own_and_converges_with_the_period() {
    let norms = AdultNorms::at(0.5).expect("the 0.50 m/s condition");
    let stride_s = 1.7535;
    let l = norms.grf_loading(stride_s, 1e-3);
    // The interpolated peak is the largest sample of the curve in the first half of
    // stance (a straight line between samples peaks at a sample).
    let half = (0.5 * norms.toe_off * (CURVE_SAMPLES - 1) as f64) as usize;
    let sampled = norms.curves.grf_vertical_bw[..=half]
        .iter()
        .copied()
        .fold(0.0, f64::max);
    assert!((l.peak - sampled).abs() < 1e-3, "{} vs {sampled}", l.peak);
    // The 20-80 % crossings on a 1 ms grid: halving the step moves the rate by under 1 %.
    let fine = norms.grf_loading(stride_s, 0.5e-3);
    assert!(
        (fine.rate / l.rate - 1.0).abs() < 0.01,
        "{} vs {}",
        fine.rate,
        l.rate
    );
    // Timed over a stride twice as long, the same curve rises half as fast.
    let slow = norms.grf_loading(2.0 * stride_s, 1e-3);
    assert!(
        (slow.rate / l.rate - 0.5).abs() < 0.01,
        "{}",
        slow.rate / l.rate
    );
}

#[test]
fn a_series_sampled_over_a_cycle_projects_back_onto_itself() {
    let hip = *GaitReference::adult(0.5, 1.7, 0.0).unwrap().hip_series();
    let samples: Vec<f64> = (0..200).map(|k| hip.value_deg(k as f64 / 200.0)).collect();
    let back = FourierSeries::project(&samples).unwrap();
    for (a, b) in hip.cos_deg.iter().zip(&back.cos_deg) {
        assert!((a - b).abs() < 1e-12, "{hip:?} vs {back:?}");
    }
    for (a, b) in hip.sin_deg.iter().zip(&back.sin_deg) {
        assert!((a - b).abs() < 1e-12, "{hip:?} vs {back:?}");
    }
    assert!(FourierSeries::project(&samples[..2 * HARMONICS]).is_none());
}

#[test]
fn a_hip_correction_adds_to_the_hip_alone() {
    let g = GaitReference::adult(0.5, 1.7, 0.0).unwrap();
    let mut c = FourierSeries::default();
    c.cos_deg[0] = 1.5;
    c.sin_deg[2] = -0.5;
    let corrected = g.with_hip_correction(&c);
    for t in [0.1, 0.4, 0.93, 1.3] {
        let (a, b) = (g.sample(t), corrected.sample(t));
        let phase = t / 1.7;
        let added = 1.5 - 0.5 * (2.0 * TAU * phase).sin();
        assert!((deg(b.hip.angle_rad - a.hip.angle_rad) - added).abs() < 1e-9);
        assert_eq!(a.knee, b.knee);
        assert_eq!(a.ankle, b.ankle);
    }
}

/// `g`'s velocities and accelerations against central differences of its samples,
/// through the start-up ramp and after it.
fn assert_derivatives_match_central_differences(g: &GaitReference) {
    let h = 1e-5;
    let mut t = 0.013;
    while t < 8.0 {
        let (a, b, c) = (g.sample(t - h), g.sample(t), g.sample(t + h));
        for (ja, jb, jc) in [(a.hip, b.hip, c.hip), (a.knee, b.knee, c.knee)] {
            let v = (jc.angle_rad - ja.angle_rad) / (2.0 * h);
            let acc = (jc.velocity_rad_s - ja.velocity_rad_s) / (2.0 * h);
            assert!((v - jb.velocity_rad_s).abs() < 1e-6, "t={t}: {v} vs {jb:?}");
            assert!(
                (acc - jb.acceleration_rad_s2).abs() < 1e-4,
                "t={t}: {acc} vs {jb:?}"
            );
        }
        t += 0.097;
    }
}

#[test]
fn derivatives_match_central_differences_through_the_ramp_and_after() {
    assert_derivatives_match_central_differences(
        &GaitReference::normative(GaitSpeed::Slow, 1.6, 2.0).unwrap(),
    );
}

fn in_step(ramp_s: f64) -> GaitReference {
    GaitReference::adult(0.5, 1.7, ramp_s)
        .unwrap()
        .with_start_up(StartUp::InStep)
        .unwrap()
}

#[test]
fn an_in_step_start_has_the_derivatives_of_its_samples() {
    assert_derivatives_match_central_differences(&in_step(3.4));
}

#[test]
fn an_in_step_start_stands_in_the_gaits_posture_and_joins_the_standing_starts_cycle() {
    for (ramp_s, start_phase) in [(1.7, 0.5), (3.4, 0.0)] {
        let g = in_step(ramp_s);
        let standing = GaitReference::adult(0.5, 1.7, ramp_s).unwrap();
        // At rest in the gait's posture, at a double-support phase of both legs.
        let s0 = g.sample(0.0);
        let posture = standing.sample(ramp_s + start_phase * 1.7);
        for (j, p) in [(s0.hip, posture.hip), (s0.knee, posture.knee)] {
            assert!((j.angle_rad - p.angle_rad).abs() < 1e-12, "{j:?} vs {p:?}");
            assert_eq!((j.velocity_rad_s, j.acceleration_rad_s2), (0.0, 0.0));
        }
        assert!(g.in_stance(0.0) && g.for_leg(1).in_stance(0.0), "{ramp_s}");
        assert!(!g.standing(0.0) && standing.standing(0.0));
        // From the ramp's end on, the same cycle at the same time as a standing start,
        // to the last bit.
        for k in 0..40 {
            let t = ramp_s + 0.05 * k as f64;
            assert_eq!(g.sample(t), standing.sample(t), "{t}");
            assert_eq!(g.phase(t), standing.phase(t), "{t}");
        }
        // The cadence grows monotonically: the phase never runs backwards.
        let walked: Vec<f64> = (0..=100)
            .map(|k| g.cycles(ramp_s * k as f64 / 100.0).0)
            .collect();
        assert!(walked.windows(2).all(|w| w[1] >= w[0]), "{walked:?}");
    }
}

#[test]
fn an_in_step_start_needs_a_ramp_of_whole_strides() {
    for ramp_s in [0.0, 1.0, 2.55] {
        let e = GaitReference::adult(0.5, 1.7, ramp_s)
            .unwrap()
            .with_start_up(StartUp::InStep)
            .unwrap_err()
            .to_string();
        assert!(e.contains("gait.ramp_s") && !e.contains('\n'), "{e}");
    }
}

#[test]
fn starts_from_standing_at_rest_and_is_periodic_after_the_ramp() {
    let g = GaitReference::normative(GaitSpeed::Slow, 1.6, 2.0).unwrap();
    let s0 = g.sample(0.0);
    for j in [s0.hip, s0.knee] {
        assert_eq!(
            (j.angle_rad, j.velocity_rad_s, j.acceleration_rad_s2),
            (0.0, 0.0, 0.0)
        );
    }
    for k in 0..50 {
        let t = 2.0 + 0.05 * k as f64;
        let (a, b) = (g.sample(t), g.sample(t + 1.6));
        assert!((a.hip.angle_rad - b.hip.angle_rad).abs() < 1e-12);
        assert!((a.knee.velocity_rad_s - b.knee.velocity_rad_s).abs() < 1e-9);
    }
}

#[test]
fn curves_have_the_normative_shape_and_stay_in_the_leg_limits() {
    for speed in GaitSpeed::ALL {
        let g = GaitReference::normative(speed, 1.0, 0.0).unwrap();
        let (mut hmin, mut hmax, mut kmin, mut kmax, mut kpeak_phase) =
            (f64::MAX, f64::MIN, f64::MAX, f64::MIN, 0.0);
        for i in 0..1000 {
            let p = i as f64 / 1000.0;
            let s = g.sample(p);
            let (h, k) = (deg(s.hip.angle_rad), deg(s.knee.angle_rad));
            hmin = hmin.min(h);
            hmax = hmax.max(h);
            kmin = kmin.min(k);
            if k > kmax {
                kmax = k;
                kpeak_phase = p;
            }
        }
        // Exoskeleton limits: hip -20..45 deg, knee 0..75 deg flexion.
        assert!(hmin > -20.0 && hmax < 45.5, "{speed}: hip {hmin}..{hmax}");
        assert!(kmin > 0.0 && kmax < 75.0, "{speed}: knee {kmin}..{kmax}");
        // Peak knee flexion in swing, at 65-80 % of the cycle; at least 40 deg.
        assert!(
            (0.65..0.80).contains(&kpeak_phase) && kmax > 40.0,
            "{speed}: knee peak {kmax} at {kpeak_phase}"
        );
    }
}

#[test]
fn toe_off_comes_later_the_slower_the_gait() {
    // Stance lengthens as walking slows (Perry and Burnfield 2010: about 60 % of the
    // cycle at free speed); Schwartz et al.'s ankle moment gives 71 % very slow, 61 %
    // free, 59 % very fast.
    let phases: Vec<f64> = GaitSpeed::ALL
        .iter()
        .map(|&s| {
            GaitReference::normative(s, 1.6, 0.0)
                .unwrap()
                .toe_off_phase()
        })
        .collect();
    assert!(phases.windows(2).all(|w| w[0] > w[1]), "{phases:?}");
    assert!((0.60..0.63).contains(&phases[2]), "{phases:?}");
    let g = GaitReference::normative(GaitSpeed::Slow, 1.6, 1.6).unwrap();
    assert!(g.in_stance(0.5) && g.in_stance(1.6 + 0.9) && !g.in_stance(1.6 + 1.1));
    // The other leg is the same cycle half a stride on.
    let (a, b) = (g.sample(4.0 + 0.8), g.sample_half_stride_later(4.0));
    assert!((a.knee.angle_rad - b.knee.angle_rad).abs() < 1e-12);
}

#[test]
fn bad_periods_are_rejected() {
    assert!(GaitReference::normative(GaitSpeed::Slow, 0.0, 1.0).is_err());
    assert!(GaitReference::normative(GaitSpeed::Slow, f64::NAN, 1.0).is_err());
    assert!(GaitReference::normative(GaitSpeed::Slow, 1.6, -1.0).is_err());
    assert!("jogging".parse::<GaitSpeed>().is_err());
    assert_eq!(
        "very-slow".parse::<GaitSpeed>().unwrap(),
        GaitSpeed::VerySlow
    );
}

#[test]
fn regression_the_other_legs_angles_alone_are_the_samples_bit_for_bit() {
    // The virtual other leg reads `angles_rad` at every substep instead of a whole sample
    // (issue 50): the trainer's figures must not move by a bit.
    let standing = GaitReference::normative(GaitSpeed::Slow, 1.6, 2.0).unwrap();
    for g in [standing, in_step(3.4)] {
        for leg in [0, 1] {
            let g = g.for_leg(leg);
            for i in -50..12_000 {
                let t = f64::from(i) * 7.3e-4;
                let s = g.sample(t);
                let [hip, knee] = g.angles_rad(t);
                assert_eq!(hip.to_bits(), s.hip.angle_rad.to_bits(), "hip at {t} s");
                assert_eq!(knee.to_bits(), s.knee.angle_rad.to_bits(), "knee at {t} s");
            }
        }
    }
}
