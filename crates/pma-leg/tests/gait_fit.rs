//! The adult reference made consistent with the trainer's belt (`pma-exo fit-gait`):
//! replayed rigidly, the data's hip drags the stance feet along the belt; the fitted hip
//! lets them move with it, and what the joints must supply falls accordingly
//! (docs/treadmill.md).
use pma_leg::gait::StartUp;
use pma_leg::ground::TreadmillSettings;
use pma_leg::tools::BeltRule;
use pma_leg::tools::{stride_demand, Demand};
use pma_leg::{fit_gait, GaitFitSettings, LoadedScenario, Scenario};

/// `gait_treadmill` with the pelvis nearly free fore-aft (the default hold) and the
/// standing start, as the trainer ran when the rigid replay's drag was found; the shipped
/// one holds the pelvis stiffly and starts in step.
fn with_the_pelvis_nearly_free() -> LoadedScenario {
    let mut loaded = Scenario::load("gait_treadmill").expect("embedded");
    loaded.scenario.gait.start_up = StartUp::Standing;
    if let Some(t) = &mut loaded.scenario.treadmill {
        let free = TreadmillSettings::new(t.bws_fraction, t.body_mass_kg);
        t.pelvis_fore_aft_n_per_m = free.pelvis_fore_aft_n_per_m;
        t.pelvis_fore_aft_damping_n_s_per_m = free.pelvis_fore_aft_damping_n_s_per_m;
    }
    loaded
}

/// RMS over the measured stance periods of the contact's speed relative to the hip plus
/// the belt's (m/s), and the feet's worst mean slip per stride (m).
fn stance_figures(d: &Demand) -> (f64, f64) {
    let t = d.treadmill.as_ref().expect("a treadmill");
    let (sq, n) = d
        .samples
        .iter()
        .filter(|s| s.contact_speed_m_s.is_finite())
        .fold((0.0, 0usize), |(sq, n), s| {
            (sq + (s.contact_speed_m_s + t.belt_speed_m_s).powi(2), n + 1)
        });
    let slip = t
        .feet
        .values()
        .map(|f| f.slip_per_stride_m.mean)
        .fold(0.0, f64::max);
    ((sq / n.max(1) as f64).sqrt(), slip)
}

#[test]
fn a_rigid_replay_of_the_adults_hip_drags_the_stance_feet_along_the_belt() {
    // The bug this pins: the data's hip, measured against a pelvis that rocked and
    // rotated, moves a stance foot back at 0.18-0.70 m/s on a trainer whose pelvis does
    // not; the feet slipped 51-53 mm per stride and the hip's servo needed 3.8 N m/kg.
    let mut loaded = with_the_pelvis_nearly_free();
    loaded.scenario.gait.hip_correction = None;
    if let Some(t) = &mut loaded.scenario.treadmill {
        t.speed_m_per_s = None;
    }
    let (error, slip) = stance_figures(&stride_demand(&loaded, 2).expect("runs"));
    eprintln!(
        "the data's hip: contact speed error {error:.4} m/s RMS, slip {:.1} mm per stride",
        1e3 * slip
    );
    assert!(error > 0.1, "{error}");
    assert!(slip > 0.04, "{slip}");
}

#[test]
fn the_fit_makes_the_stance_contact_move_at_the_belts_speed() {
    // Three learning runs from the data already take out most of the speed error (with
    // the pelvis held, the shipped case, the fit starts nearer and converges more slowly:
    // docs/treadmill.md).
    let loaded = with_the_pelvis_nearly_free();
    let settings = GaitFitSettings {
        iterations: 3,
        strides: 2,
        belt: BeltRule::StanceMean,
        ..Default::default()
    };
    let fit = fit_gait(&loaded, &settings, || false).expect("fits");
    let errors: Vec<f64> = fit
        .steps
        .iter()
        .map(|s| s.contact_speed_error_rms_m_s)
        .collect();
    eprintln!("contact speed error RMS per run: {errors:.4?} m/s");
    assert_eq!(fit.steps.len(), 4);
    assert_eq!(fit.best, 3, "{errors:?}");
    assert!(errors[3] < errors[0] / 4.0, "{errors:?}");
    assert!(
        errors.windows(2).all(|w| w[1] < w[0]),
        "each run improves: {errors:?}"
    );
}

/// The bands every shipped two-leg fit meets, servo-driven as `pma-exo size` runs
/// it: slip under 20 mm per stride, stance within 3 % of the cycle of the reference's, no
/// scuff, at most 1.2 N m/kg at the hip and 1.0 at the knee, the belt within 1 N of no
/// mean harness force (8 N per mm/s; the shipped belt has 4 decimals), and the pelvis off
/// its stops. Returns each foot's largest loading peak over the belt's mean load.
fn assert_the_stance_feet_move_with_the_belt(name: &str) -> Vec<f64> {
    // Regression (issue 50): the belts and hip corrections were fitted at one physics
    // substep and checked at it after the scenarios moved to two, where the harness's mean
    // was -3.0 N (`gait_treadmill`) and -4.0 N (`gait_treadmill_unsupported`). They are
    // refitted at the shipped step and checked as shipped.
    let loaded = Scenario::load(name).expect("embedded");
    let d = stride_demand(&loaded, 3).expect("runs");
    let body_mass_kg = loaded
        .scenario
        .treadmill
        .map_or(f64::NAN, |t| t.body_mass_kg);
    let (error, slip) = stance_figures(&d);
    let t = d.treadmill.as_ref().expect("a treadmill");
    let peak_kg = |j: usize| {
        let [lo, hi] = d.torque_range_nm(j);
        lo.abs().max(hi.abs()) / body_mass_kg
    };
    let ratios: Vec<f64> = t
        .feet
        .values()
        .map(|f| f.peak_grf_bw.max / t.expected_belt_load_bw)
        .collect();
    eprintln!(
        "{name}: contact speed error {error:.4} m/s RMS, slip {:.1} mm per stride, peak demand {:.2} / {:.2} N m/kg, loading peak / belt load {ratios:.3?}, pelvis at its fore-aft stop {:.0} % of the time",
        1e3 * slip,
        peak_kg(0),
        peak_kg(1),
        100.0 * t.pelvis_at_fore_aft_stop
    );
    // Period by period (the fit averages its strides in phase bins: 0.0066 m/s there).
    assert!(error < 0.03, "{error}");
    assert!(slip < 0.02, "{slip}");
    for (side, f) in &t.feet {
        assert!(
            (f.stance_fraction.mean - f.reference_stance_fraction).abs() < 0.03,
            "{side}: {f:?}"
        );
        assert_eq!(f.scuffs, 0, "{side}: {f:?}");
    }
    assert!(peak_kg(0) <= 1.2, "{}", peak_kg(0));
    assert!(peak_kg(1) <= 1.0, "{}", peak_kg(1));
    assert!(
        t.harness_fore_aft_n.mean.abs() < 1.0,
        "{:?}",
        t.harness_fore_aft_n
    );
    // Regression: the harness's figures once began a stride before the measured ones and
    // reported the start-up's 480 N, as the belt came up to speed, as the gait's (-43..53
    // N over the measured strides).
    let h = &t.harness_fore_aft_n;
    assert!(h.max < 150.0 && h.min > -150.0, "{h:?}");
    // Regression (issue 27): the pelvis, nearly free, rested on its rear stop 62 % of the
    // time, which then held the trainer with a force no output measured; held, it never
    // reaches it.
    assert_eq!(t.pelvis_at_fore_aft_stop, 0.0, "{t:?}");
    ratios
}

#[test]
fn on_the_shipped_fit_the_stance_feet_move_with_the_belt() {
    // The shipped scenario's correction (`pma-exo fit-gait gait_treadmill --iterations
    // 60`, the pelvis held fore-aft). Regression (issue 27): with the belt at the stance
    // contact's mean speed, 1 % faster than the feet, the belt dragged the patient against
    // the harness (58 N) and the hip's peak was 1.40 N m/kg (1.80 with the pelvis nearly
    // free).
    let ratios = assert_the_stance_feet_move_with_the_belt("gait_treadmill");
    // The band, 1.0-1.25 times the belt's load (walking without support peaks at
    // 1.0-1.2 BW). It was loosened to 0.95 while the belt dragged the feet (the left
    // foot's largest peak 0.98); without the drag it was 1.01 (left) and 1.11 (right), and
    // 1.02 on both feet since the refit at two physics substeps (issue 50).
    for r in ratios {
        assert!((1.0..=1.25).contains(&r), "{r}");
    }
}

#[test]
fn without_support_the_trainer_walks_once_the_foot_lifter_clears_the_swing_toe() {
    // `gait_treadmill_unsupported`: 0 % support (after a supported start-up), the foot
    // lifter at +6 deg, refitted (`pma-exo fit-gait gait_treadmill_unsupported
    // --iterations 60`). The feet sink deeper than at 30 %, and at gait_treadmill's +5 deg
    // the swing toe scuffed the belt in terminal swing (three scuffs per foot in four
    // strides; 9.9 / 5.9 N m/kg).
    let ratios = assert_the_stance_feet_move_with_the_belt("gait_treadmill_unsupported");
    // Measured 0.986 on both feet (0.984 before the refit at two physics substeps): just
    // under the 1.0-1.25, which this does not meet (docs/treadmill.md); pinned
    // here so that it cannot fall unnoticed.
    for r in ratios {
        assert!((0.98..=1.25).contains(&r), "{r}");
    }
}

#[test]
fn the_belt_search_ends_where_the_harness_carries_no_mean_force() {
    // The held pelvis's harness force grows with the belt's speed (about 8 N per mm/s);
    // the secant runs on the fitted hip end within the tolerance, and the belt kept is the
    // run of least |force|.
    let loaded = Scenario::load("gait_treadmill").expect("embedded");
    let settings = GaitFitSettings {
        iterations: 1,
        strides: 1,
        ..Default::default()
    };
    let fit = fit_gait(&loaded, &settings, || false).expect("fits");
    let runs: Vec<(f64, f64)> = fit
        .belt_steps
        .iter()
        .map(|s| (s.belt_speed_m_s, s.harness_fore_aft_mean_n))
        .collect();
    eprintln!("belt (m/s), harness mean (N) per run: {runs:.4?}");
    let first = runs.first().expect("a belt run");
    let last = runs.last().expect("a belt run");
    // The hip's rule leaves a drag: the belt runs faster than the feet.
    assert!(first.1 > 10.0, "{runs:?}");
    assert!(last.1.abs() < 0.5, "{runs:?}");
    assert!(last.0 < first.0, "{runs:?}");
    assert!(runs.len() < 8, "{runs:?}");
    assert_eq!(fit.belt_speed_m_s, last.0);
}

#[test]
fn regression_a_fitted_scenario_refits_to_the_correction_it_holds() {
    // The fit once kept the scenario's own belt speed for its first run: fitting a fitted
    // scenario then started elsewhere and gave another correction than the one the
    // scenario's comment says the same command gave. The first run is the data's at the
    // reference's belt speed, as for a scenario without a fit.
    let fitted = Scenario::load("gait_treadmill_one_leg").expect("embedded");
    let mut bare = fitted.clone();
    bare.scenario.gait.hip_correction = None;
    if let Some(t) = &mut bare.scenario.treadmill {
        t.speed_m_per_s = None;
    }
    let settings = GaitFitSettings {
        iterations: 1,
        strides: 1,
        belt: BeltRule::StanceMean,
        ..Default::default()
    };
    let [a, b] = [&fitted, &bare].map(|l| fit_gait(l, &settings, || false).expect("fits"));
    assert_eq!(a.steps, b.steps);
    assert_eq!(a.hip_correction, b.hip_correction);
}
