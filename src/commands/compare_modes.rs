//! `pma-exo compare-modes`: one patient under position, impedance, path and transparent
//! control, and with the muscles unhooked (the patient alone with the frames): what the
//! device does to the patient and how the patient walks (issue 28).
use crate::say;
use anyhow::Result;
use pma_leg::control::PhaseSync;
use pma_leg::{ControlMode, LegError, LegReport, LegSim, LoadedScenario, Scenario};
use rayon::prelude::*;
use serde::Serialize;

/// `compare-modes`' arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Scenarios, comma-separated (embedded names or .toml files).
    #[arg(long, value_delimiter = ',', default_values_t = ["gait_active".to_owned(), "gait_spasms".to_owned()])]
    scenarios: Vec<String>,
    /// Simulated seconds per run; at least two strides.
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    duration: f64,
    /// Worker threads (default: one per core); the results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Admittance mode again at each of these joint stiffnesses (N m/rad, both joints,
    /// comma-separated): from patient-in-charge towards robot-in-charge, beyond what
    /// co-contraction reaches.
    #[arg(long, value_delimiter = ',', value_name = "N m/rad")]
    admittance_stiffness: Vec<f64>,
    /// Impedance and admittance mode again with the gait's clock following the legs'
    /// lead at this gain (1/s, 0-20; `control.impedance.phase_sync_per_s`).
    #[arg(long, value_name = "1/s", allow_negative_numbers = true)]
    phase_sync: Option<f64>,
    /// The clock's integral gain for those rows (1/s², below the gain over the stride
    /// period; `control.impedance.phase_sync_integral_per_s2`).
    #[arg(
        long,
        value_name = "1/s²",
        default_value_t = 0.0,
        requires = "phase_sync",
        allow_negative_numbers = true
    )]
    phase_sync_integral: f64,
    /// Print JSON instead of tables.
    #[arg(long)]
    json: bool,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// How a run drives the leg.
#[derive(Clone, Copy, Serialize)]
#[serde(rename_all = "snake_case")]
enum Drive {
    /// A control mode (position: the scenario's APRC-NDO).
    Mode(ControlMode),
    /// Admittance mode (APRC-NDO) with both joints at this stiffness (N m/rad).
    AdmittanceAt(f64),
    /// Every muscle vented and unhooked: the patient alone with the frames.
    Unhooked,
    /// A yielding mode whose gait clock follows the legs (gain 1/s, integral 1/s²).
    Following(ControlMode, f64, f64),
}

impl Drive {
    fn name(self) -> String {
        match self {
            Drive::Mode(ControlMode::Position) => "position (APRC-NDO)".into(),
            Drive::Mode(ControlMode::Admittance) => "admittance (APRC-NDO)".into(),
            Drive::Mode(m) => m.to_string(),
            Drive::AdmittanceAt(k) => format!("admittance (APRC-NDO), {k} N m/rad"),
            Drive::Unhooked => "muscles unhooked".into(),
            Drive::Following(m, gain, integral) => {
                let mode = Drive::Mode(m).name();
                if integral > 0.0 {
                    format!("{mode}, clock following ({gain} /s, {integral} /s²)")
                } else {
                    format!("{mode}, clock following ({gain} /s)")
                }
            }
        }
    }
}

const DRIVES: [Drive; 6] = [
    Drive::Mode(ControlMode::Position),
    Drive::Mode(ControlMode::Impedance),
    Drive::Mode(ControlMode::Admittance),
    Drive::Mode(ControlMode::Path),
    Drive::Mode(ControlMode::Transparent),
    Drive::Unhooked,
];

/// One run's figures.
#[derive(Serialize)]
struct Row {
    scenario: String,
    mode: String,
    /// Tracking RMS against the device's reference, hip and knee (deg).
    tracking_rms_deg: [f64; 2],
    /// RMS and peak of the torque the device puts into the limb, hip and knee (N m).
    interaction_rms_nm: [f64; 2],
    interaction_peak_nm: [f64; 2],
    /// Work of the patient's torques and of the device's on the limb, both joints (J).
    patient_work_j: f64,
    device_work_j: f64,
    strides: usize,
    stride_time_cv: f64,
    hip_peak_sd_deg: f64,
    knee_peak_sd_deg: f64,
    inside_tunnel_share: f64,
    /// The largest spasm deviation (deg; NaN without spasms).
    spasm_deviation_max_deg: f64,
    /// The largest muscle force over its rating (NaN with the muscles unhooked: they
    /// pull on nothing).
    peak_force_over_rating: f64,
    /// The largest pressure rate (bar/s; NaN unhooked).
    peak_pressure_rate_bar_s: f64,
    /// Time either joint spent beyond its URDF limits (s): the stops' impacts are in the
    /// interaction peaks.
    beyond_limits_s: f64,
}

fn row(scenario: &str, drive: Drive, r: &LegReport) -> Row {
    let c = r.cooperation.first().cloned().unwrap_or_default();
    let joint = |name: &str| c.joints.get(name).copied().unwrap_or_default();
    let (hip, knee) = (joint("hip"), joint("knee"));
    let rms = |name: &str| r.joints.get(name).map_or(f64::NAN, |j| j.rms_deg);
    let muscles = r.safety.muscles.values();
    let hooked = !matches!(drive, Drive::Unhooked);
    let worst = |f: fn(&pma_leg::metrics::MuscleSafety) -> f64| {
        if hooked {
            muscles.clone().map(f).fold(0.0, f64::max)
        } else {
            f64::NAN
        }
    };
    Row {
        scenario: scenario.to_owned(),
        mode: drive.name(),
        tracking_rms_deg: [rms("hip"), rms("knee")],
        interaction_rms_nm: [hip.interaction_rms_nm, knee.interaction_rms_nm],
        interaction_peak_nm: [hip.interaction_peak_nm, knee.interaction_peak_nm],
        patient_work_j: hip.patient_work_j + knee.patient_work_j,
        device_work_j: hip.device_work_j + knee.device_work_j,
        strides: c.strides,
        stride_time_cv: c.stride_time_cv,
        hip_peak_sd_deg: c.hip_peak_sd_deg,
        knee_peak_sd_deg: c.knee_peak_sd_deg,
        inside_tunnel_share: c.inside_tunnel_share,
        spasm_deviation_max_deg: r
            .spasms
            .iter()
            .map(|s| s.peak_deviation_deg)
            .fold(f64::NAN, f64::max),
        peak_force_over_rating: worst(|m| m.peak_over_rated),
        peak_pressure_rate_bar_s: worst(|m| m.peak_pressure_rate_bar_s),
        beyond_limits_s: r.safety.joints.values().map(|j| j.time_outside_s).sum(),
    }
}

/// `loaded` set up to run as `drive` says.
fn driven(loaded: &LoadedScenario, drive: Drive) -> LoadedScenario {
    let mut loaded = loaded.clone();
    let control = &mut loaded.scenario.control;
    match drive {
        Drive::Mode(m) => control.mode = m,
        Drive::AdmittanceAt(k) => {
            control.mode = ControlMode::Admittance;
            control.impedance.hip.stiffness_nm_per_rad = Some(k);
            control.impedance.knee.stiffness_nm_per_rad = Some(k);
        }
        Drive::Unhooked => {}
        Drive::Following(m, gain, integral) => {
            control.mode = m;
            control.impedance.phase_sync_per_s = gain;
            control.impedance.phase_sync_integral_per_s2 = integral;
        }
    }
    loaded
}

fn run_one(
    loaded: &LoadedScenario,
    drive: Drive,
    duration_s: f64,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<LegReport> {
    let mut sim = LegSim::new(&driven(loaded, drive))?;
    if let Drive::Unhooked = drive {
        sim.release_muscles()?;
    }
    let settings = sim.settings(duration_s)?.with_stop_flag(stop);
    Ok(sim.run_with(&settings, &mut ())?)
}

/// Runs `compare-modes`.
pub fn run(a: Args) -> Result<i32> {
    super::check_duration(a.duration)?;
    let scenarios = a
        .scenarios
        .iter()
        .map(|s| Scenario::load(s))
        .collect::<Result<Vec<_>, _>>()?;
    for s in &scenarios {
        s.scenario.check_run_duration(a.duration)?;
        if s.scenario.treadmill.is_some() {
            anyhow::bail!(
                "--scenarios {}: compare-modes runs the leg in the air (on the treadmill the pressure-set modes do not walk a patient below 85 % support: docs/cooperative.md)",
                s.scenario.name
            );
        }
    }
    if let Some(k) = a
        .admittance_stiffness
        .iter()
        .find(|k| !pma_leg::control::stiffness_in_range(**k))
    {
        anyhow::bail!(
            "--admittance-stiffness {k}: each must be > 0 and at most {} N m/rad",
            pma_leg::control::STIFFNESS_MAX_NM_PER_RAD
        );
    }
    let following: Vec<Drive> = a
        .phase_sync
        .map(|gain| {
            [ControlMode::Impedance, ControlMode::Admittance]
                .map(|m| Drive::Following(m, gain, a.phase_sync_integral))
        })
        .into_iter()
        .flatten()
        .collect();
    check_following(&scenarios, &a)?;
    let drives: Vec<Drive> = DRIVES
        .iter()
        .copied()
        .chain(following.iter().copied())
        .chain(
            a.admittance_stiffness
                .iter()
                .map(|k| Drive::AdmittanceAt(*k)),
        )
        .collect();
    let jobs: Vec<(usize, Drive)> = (0..scenarios.len())
        .flat_map(|i| drives.iter().map(move |d| (i, *d)))
        .collect();
    let periods: f64 = jobs
        .iter()
        .map(|(i, _)| a.duration / scenarios[*i].scenario.period_s)
        .sum();
    super::check_leg_comparison(periods, a.yes)?;
    let stop = crate::output::stop_flag()?;
    let reports = super::with_threads(a.threads, || {
        jobs.par_iter()
            .map(|(i, d)| run_one(&scenarios[*i], *d, a.duration, &stop))
            .collect::<Result<Vec<_>>>()
    })??;
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        eprintln!("interrupted: no row is kept (a comparison of runs cut short compares nothing)");
        return Ok(crate::output::INTERRUPTED);
    }
    let rows: Vec<Row> = jobs
        .iter()
        .zip(&reports)
        .map(|((i, d), r)| row(&a.scenarios[*i], *d, r))
        .collect();
    let provenance = crate::provenance::Provenance {
        scenario: Some(a.scenarios.join(", ")),
        ..crate::provenance::Provenance::of_this_run()
    };
    if a.json {
        let json = serde_json::json!({ "provenance": provenance, "rows": rows });
        say!("{}", serde_json::to_string(&json)?);
        return Ok(0);
    }
    say!("{}", table(&rows, a.duration));
    say!("{}", provenance.line());
    Ok(0)
}

/// Checks `--phase-sync` and `--phase-sync-integral` against each scenario's stride where
/// the clock is built ([`PhaseSync::new`]), before any run starts: one error naming the
/// option.
fn check_following(scenarios: &[LoadedScenario], a: &Args) -> Result<()> {
    let Some(gain) = a.phase_sync else {
        return Ok(());
    };
    if gain == 0.0 {
        anyhow::bail!("--phase-sync 0: must be > 0 (0 leaves the gait on its own clock)");
    }
    for s in scenarios {
        let stride = s.scenario.gait.reference()?.stride_period_s();
        if let Err(e) = PhaseSync::new(gain, a.phase_sync_integral, stride, 0.0) {
            let option = match &e {
                LegError::Invalid(i) if i.name.contains("integral") => {
                    format!("--phase-sync-integral {}", a.phase_sync_integral)
                }
                _ => format!("--phase-sync {gain}"),
            };
            anyhow::bail!("{option} ({}): {e}", s.scenario.name);
        }
    }
    Ok(())
}

fn table(rows: &[Row], duration_s: f64) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let mut last = "";
    for r in rows {
        if r.scenario != last {
            let _ = writeln!(
                out,
                "\n### {} ({duration_s} s)\n\n| mode | tracking RMS hip / knee (deg) | interaction RMS hip / knee (N m) | interaction peak hip / knee (N m) | patient / device work (J) | stride time CV | peak SD hip / knee (deg) | inside the tunnel | largest spasm deviation (deg) | peak force / rating | peak pressure rate (bar/s) | beyond the URDF limits (s) |\n|---|---|---|---|---|---|---|---|---|---|---|---|",
                r.scenario
            );
            last = &r.scenario;
        }
        let _ = writeln!(
            out,
            "| {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.1} / {:.1} | {:.1} / {:.1} | {:.3} | {:.2} / {:.2} | {:.1} % | {:.2} | {:.2} | {:.0} | {:.2} |",
            r.mode,
            r.tracking_rms_deg[0],
            r.tracking_rms_deg[1],
            r.interaction_rms_nm[0],
            r.interaction_rms_nm[1],
            r.interaction_peak_nm[0],
            r.interaction_peak_nm[1],
            r.patient_work_j,
            r.device_work_j,
            r.stride_time_cv,
            r.hip_peak_sd_deg,
            r.knee_peak_sd_deg,
            100.0 * r.inside_tunnel_share,
            r.spasm_deviation_max_deg,
            r.peak_force_over_rating,
            r.peak_pressure_rate_bar_s,
            r.beyond_limits_s
        );
    }
    out
}
