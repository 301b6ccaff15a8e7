//! The patient in the leg: every controller against every patient scenario, the stretch
//! reflex's velocity dependence and delay, reproducible spasms, the inverse dynamics the
//! voluntary effort uses, and the pendulum test's physics.
use pma_control::ControllerKind;
use pma_leg::gait::GaitReference;
use pma_leg::patient::{
    JointPatientSettings, PatientSettings, PatientTorques, SpasticityPreset, SpasticitySettings,
};
use pma_leg::{LegOutput, LegReport, LegSim, Patient, PerLeg, Scenario, SupervisedLeg, Vented};
use pma_loop::{FnRecorder, LoopSettings, Period};
use pma_studies::pendulum::{self, PendulumSetup};

mod common;
use common::LONG_RUN_SUBSTEPS;

const CONTROLLERS: [ControllerKind; 5] = [
    ControllerKind::AprcNdo,
    ControllerKind::Psmc,
    ControllerKind::NdoSmc,
    ControllerKind::Sta,
    ControllerKind::Pid,
];

/// A run of `kind` on `scenario` at `substeps` physics steps a period (`None`: the
/// scenario's own), with the largest |torque| of `part` of the patient at hip and knee over
/// the run (N m).
fn run(
    scenario: &str,
    kind: ControllerKind,
    duration_s: f64,
    substeps: Option<u32>,
    part: PatientPart,
) -> (LegReport, [f64; 2]) {
    let loaded = common::scenario_at(scenario, substeps);
    let config = pma_leg::control::leg_gains(kind).expect("gains");
    let mut sim = LegSim::with_controller(&loaded, &config).expect("sim");
    let mut peak = [0.0f64; 2];
    let mut rec = FnRecorder(|p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>| {
        let tau = part(&p.truth.legs[0].patient);
        for j in 0..2 {
            peak[j] = peak[j].max(tau[j].abs());
        }
    });
    let report = sim.run(duration_s, &mut rec).expect("run");
    (report, peak)
}

/// Every controller on `scenario` for 60 s at `substeps` (`None`: the scenario's own);
/// `part` is what the scenario's patient does, which must act at both joints.
fn every_controller_for_60_s(scenario: &str, substeps: Option<u32>, part: PatientPart) {
    for kind in CONTROLLERS {
        let (r, peak) = run(scenario, kind, 60.0, substeps, part);
        eprintln!(
            "{scenario} {kind} ({substeps:?} substeps): hip RMS {:.3} deg, knee RMS {:.3} deg, patient knee RMS {:.2} N m, {} spasms",
            r.joints["hip"].rms_deg,
            r.joints["knee"].rms_deg,
            r.patient.joints["knee"].torque_rms_nm,
            r.spasms.len()
        );
        assert!(r.finite, "{scenario} {kind}: non-finite");
        for (name, m) in &r.muscles {
            assert!(
                m.p_min_pa >= 0.0 && m.p_max_pa <= 6.0e5,
                "{scenario} {kind} {name}: {m:?}"
            );
        }
        for j in r.joints.values() {
            assert!(j.rms_deg.is_finite() && j.max_deg.is_finite(), "{j:?}");
        }
        // The part acted at both joints, with more than the 1 N m of a rounding slip.
        assert!(
            peak.iter().all(|p| *p > 1.0),
            "{scenario} {kind}: peak {peak:?} N m"
        );
        for s in &r.spasms {
            assert!(s.peak_deviation_deg.is_finite() && s.peak_pressure_rate_bar_s.is_finite());
        }
    }
}

/// What a scenario's patient does, at hip and knee (N m).
type PatientPart = fn(&PatientTorques) -> [f64; 2];

/// The patients' scenarios and what each one's patient does.
const PATIENTS: [(&str, PatientPart); 3] = [
    ("gait_spastic", |t| t.reflex_nm),
    ("gait_spasms", |t| t.spasm_nm),
    ("gait_resistive", |t| t.effort_nm),
];

#[test]
fn every_controller_runs_gait_spastic_for_60_s() {
    every_controller_for_60_s(PATIENTS[0].0, Some(LONG_RUN_SUBSTEPS), PATIENTS[0].1);
}

#[test]
fn every_controller_runs_gait_spasms_for_60_s() {
    every_controller_for_60_s(PATIENTS[1].0, Some(LONG_RUN_SUBSTEPS), PATIENTS[1].1);
}

#[test]
fn every_controller_runs_gait_resistive_for_60_s() {
    every_controller_for_60_s(PATIENTS[2].0, Some(LONG_RUN_SUBSTEPS), PATIENTS[2].1);
}

/// The three tests above at the scenarios' shipped step (`LONG_RUN_SUBSTEPS` says why not
/// in every run).
#[test]
#[ignore = "about 10 min: the shipped 64 substeps; cargo test --test patient -- --ignored"]
fn every_controller_runs_the_patients_for_60_s_at_the_shipped_step() {
    for (scenario, part) in PATIENTS {
        every_controller_for_60_s(scenario, None, part);
    }
}

fn knee_reflex(preset: SpasticityPreset) -> PatientSettings {
    PatientSettings {
        knee: JointPatientSettings {
            spasticity: Some(SpasticitySettings {
                preset: Some(preset),
                ..SpasticitySettings::default()
            }),
            ..JointPatientSettings::default()
        },
        ..PatientSettings::default()
    }
}

/// The knee moved at `speed_rad_s` from `onset_s` on (an isokinetic stretch), with the
/// patient's knee torque every substep of `h_s`: `(t, torque)`.
fn isokinetic(patient: &mut Patient, speed_rad_s: f64, onset_s: f64, h_s: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut q = 0.2;
    for k in 0..(0.5 / h_s) as usize {
        let t = k as f64 * h_s;
        let w = if t >= onset_s { speed_rad_s } else { 0.0 };
        let tau = patient.torques(t, [0.0, q], [0.0, w]).reflex_nm[1];
        out.push((t, tau));
        q += w * h_s;
    }
    out
}

fn patient(settings: &PatientSettings, h_s: f64) -> Patient {
    let loaded = Scenario::load("gait_training").unwrap();
    let sim = LegSim::new(&loaded).unwrap();
    let gait = GaitReference::normative(pma_leg::gait::GaitSpeed::Slow, 1.6, 1.6).unwrap();
    Patient::new(settings, h_s, gait, *sim.exo().inertia(), [0.5, 0.5]).unwrap()
}

#[test]
fn the_reflex_acts_only_above_its_threshold_grows_with_speed_and_honours_its_delay() {
    let h = 0.5e-3;
    let r = SpasticityPreset::Moderate.knee();
    let (onset, th) = (0.1, r.threshold_rad_s);
    let mut steady = Vec::new();
    for factor in [0.5, 0.95, 1.5, 3.0] {
        let speed = factor * th;
        let mut p = patient(&knee_reflex(SpasticityPreset::Moderate), h);
        let trace = isokinetic(&mut p, speed, onset, h);
        let last = trace.last().unwrap().1;
        if factor < 1.0 {
            assert!(
                trace.iter().all(|(_, tau)| *tau == 0.0),
                "{speed} rad/s is below the {th} rad/s threshold: {last} N m"
            );
            continue;
        }
        // Flexion stretches the extensors: the reflex extends (negative torque).
        let expected = -r.extensor_gain_nm_s_per_rad * (speed - th);
        assert!(
            (last - expected).abs() < 1e-9,
            "{speed} rad/s: {last} vs {expected} N m"
        );
        // The first non-zero torque comes one delay after the stretch began, to the substep.
        let first = trace.iter().find(|(_, tau)| *tau != 0.0).unwrap().0;
        assert!(
            (first - (onset + r.delay_s)).abs() <= h + 1e-12,
            "onset at {first} s, stretch at {onset} s, delay {} s",
            r.delay_s
        );
        steady.push(last.abs());
        // Stretching the flexors (extension) gives the flexors' (smaller) reflex, flexing.
        let mut p = patient(&knee_reflex(SpasticityPreset::Moderate), h);
        let back = isokinetic(&mut p, -speed, onset, h).last().unwrap().1;
        let expected = r.flexor_gain_nm_s_per_rad * (speed - th);
        assert!((back - expected).abs() < 1e-9, "{back} vs {expected}");
    }
    assert!(steady.windows(2).all(|w| w[1] > w[0]), "{steady:?}");
}

fn spasm_times(kind: ControllerKind, seed: u64) -> Vec<(String, f64, f64, f64)> {
    // When a spasm comes is the patient's, not the step's: the cheap step of long runs.
    let mut loaded = common::scenario_at("gait_spasms", Some(LONG_RUN_SUBSTEPS));
    if let Some(s) = &mut loaded.scenario.patient.knee.spasms {
        s.seed = seed;
    }
    let config = pma_leg::control::leg_gains(kind).unwrap();
    let mut sim = LegSim::with_controller(&loaded, &config).unwrap();
    let r = sim.run(40.0, &mut ()).unwrap();
    r.spasms
        .iter()
        .map(|s| (s.joint.clone(), s.t_s, s.amplitude_nm, s.duration_s))
        .collect()
}

#[test]
fn spasms_come_at_the_same_times_with_any_controller_and_change_with_the_seed() {
    let reference = spasm_times(ControllerKind::AprcNdo, 10);
    assert!(reference.len() >= 3, "{reference:?}");
    for kind in [ControllerKind::Pid, ControllerKind::Sta] {
        assert_eq!(spasm_times(kind, 10), reference, "{kind}");
    }
    assert_eq!(spasm_times(ControllerKind::AprcNdo, 10), reference);
    let knee = |v: &[(String, f64, f64, f64)]| -> Vec<f64> {
        v.iter().filter(|e| e.0 == "knee").map(|e| e.1).collect()
    };
    assert_ne!(
        knee(&spasm_times(ControllerKind::AprcNdo, 11)),
        knee(&reference)
    );
}

#[test]
fn assisting_at_100_percent_with_vented_muscles_follows_the_reference() {
    // The patient's effort is the reference's inverse dynamics: with it alone moving the
    // leg (muscles vented and unhooked), from the reference's start state, the leg walks.
    let mut loaded = Scenario::load("gait_training").unwrap();
    for j in [
        &mut loaded.scenario.patient.hip,
        &mut loaded.scenario.patient.knee,
    ] {
        j.effort = Some(pma_leg::patient::EffortSettings {
            fraction: 1.0,
            delay_s: 0.0,
        });
    }
    let mut sim = LegSim::new(&loaded).unwrap();
    sim.release_muscles().unwrap();
    let stride = loaded.scenario.gait.stride_period_s;
    // The ramp and then one full stride.
    let duration = loaded.scenario.gait.ramp_s + stride;
    let mut task = Vented::gait(sim.gait_reference().unwrap());
    let (mut sq, mut n, mut worst) = (0.0, 0usize, 0.0f64);
    let mut rec = FnRecorder(|p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>| {
        for j in 0..2 {
            let e = (p.output[0].reference_rad[j] - p.truth.legs[0].angle_rad[j]).to_degrees();
            sq += e * e;
            n += 1;
            worst = worst.max(e.abs());
        }
    });
    let settings = LoopSettings::new(duration).unwrap();
    sim.run_task(&mut task, &mut rec, &settings).unwrap();
    let rms = (sq / n as f64).sqrt();
    eprintln!("assist 100 %, vented: RMS {rms:.4} deg, max {worst:.4} deg over {duration} s");
    assert!(rms < 2.0, "RMS {rms} deg");
}

fn pendulum_r2(preset: SpasticityPreset) -> pendulum::PendulumReport {
    let mut loaded = Scenario::load("gait_training").unwrap();
    loaded.scenario.patient = knee_reflex(preset);
    let sim = pendulum::seated(&loaded, PendulumSetup::default()).unwrap();
    let settings = LoopSettings::new(10.0).unwrap();
    pendulum::run(sim, PendulumSetup::default(), &settings, &mut ()).unwrap()
}

#[test]
fn pendulum_r2_is_healthy_without_reflex_and_falls_with_severity() {
    let presets = [
        SpasticityPreset::None,
        SpasticityPreset::Mild,
        SpasticityPreset::Moderate,
        SpasticityPreset::Severe,
    ];
    let r: Vec<_> = presets.iter().map(|p| pendulum_r2(*p)).collect();
    for (p, x) in presets.iter().zip(&r) {
        eprintln!(
            "{p:?}: R2 {:.3}, {} oscillations, first peak {:.1} deg",
            x.r2.expect("settled"),
            x.oscillations,
            x.first_peak_deg
        );
    }
    // Healthy adults: 1.678 +- 0.090 (Kim et al. 1996); the passive leg within 2 SD.
    let r2: Vec<f64> = r.iter().map(|x| x.r2.expect("settled in 10 s")).collect();
    assert!((r2[0] - 1.678).abs() < 0.18, "no reflex: R2 {}", r2[0]);
    assert!(
        r2.windows(2).all(|w| w[1] < w[0]),
        "R2 must fall with severity"
    );
    assert!(r[3].oscillations < r[0].oscillations);
}

#[test]
fn pendulum_rejects_a_knee_released_where_it_hangs() {
    let loaded = Scenario::load("gait_training").unwrap();
    let setup = PendulumSetup {
        hip_rad: 0.0,
        knee_rad: 88f64.to_radians(),
    };
    let e = pendulum::seated(&loaded, setup)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("knee"), "{e}");
}
