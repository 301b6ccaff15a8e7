//! Controllers side by side on leg scenarios: every pair run in parallel (rayon), each
//! reduced to one row of tracking, spasm and safety figures.
use pma_control::ControllerConfig;
use pma_leg::LegError;
use pma_leg::LegReport;
use pma_leg::LegSim;
use pma_leg::LoadedScenario;
use rayon::prelude::*;

/// One controller on one scenario.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CompareRow {
    /// Scenario name.
    pub scenario: String,
    /// Controller name.
    pub controller: String,
    /// Hip tracking error after the first stride, RMS (deg).
    pub hip_rms_deg: f64,
    /// Knee tracking error after the first stride, RMS (deg).
    pub knee_rms_deg: f64,
    /// Spasms in the run.
    pub spasms: usize,
    /// Mean over the spasms of their peak deviation from the reference (deg; `None`
    /// without spasms).
    pub spasm_mean_deviation_deg: Option<f64>,
    /// Largest peak deviation of a spasm (deg; `None` without spasms).
    pub spasm_max_deviation_deg: Option<f64>,
    /// Largest recovery time to within 1 deg of a spasm that recovered (s; `None` if no
    /// spasm recovered).
    pub spasm_max_recovery_s: Option<f64>,
    /// Spasms after which the joint was not back within 1 deg within 3 s or before the
    /// joint's next spasm (overlapped ones not counted).
    pub spasms_unrecovered: usize,
    /// Spasms overlapped by the joint's next one before they ended (no recovery to time).
    pub spasms_overlapped: usize,
    /// Largest muscle |dp/dt| during a spasm or its follow-up (bar/s; `None` without
    /// spasms).
    pub spasm_peak_pressure_rate_bar_s: Option<f64>,
    /// Largest muscle |dp/dt| over the run (bar/s).
    pub peak_pressure_rate_bar_s: f64,
    /// Mean |du/dt| of the commands (bar/s).
    pub command_variation_bar_per_s: f64,
    /// Largest muscle force over its rating.
    pub peak_force_over_rated: f64,
    /// Valve saturation, summed over the muscles (s).
    pub valve_saturated_s: f64,
    /// Time beyond the URDF joint limits, summed over the joints (s).
    pub time_outside_limits_s: f64,
    /// Time a muscle's force was above its rating, summed over the muscles (s).
    pub time_over_rated_s: f64,
    /// Smallest margin of a muscle's peak force to its rating (N; negative: exceeded).
    pub min_force_margin_n: f64,
    /// Time beyond the normal range of motion, summed over the joints (s).
    pub time_beyond_normal_range_s: f64,
    /// On a treadmill: the gait phases, the ground reaction and the heel strikes.
    pub treadmill: Option<TreadmillRow>,
    /// Every figure finite.
    pub finite: bool,
}

/// A run's treadmill figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TreadmillRow {
    /// Hip RMS error in stance and in swing (deg).
    pub hip_stance_swing_rms_deg: [f64; 2],
    /// Knee RMS error in stance and in swing (deg).
    pub knee_stance_swing_rms_deg: [f64; 2],
    /// Mean loading peak of the vertical GRF (body weights).
    pub peak_grf_bw: f64,
    /// Mean loading rate at heel strike (body weights per second).
    pub loading_rate_bw_s: f64,
    /// Mean stance fraction and the reference's.
    pub stance_fraction: [f64; 2],
    /// Mean slip per stride (m).
    pub slip_per_stride_m: f64,
    /// Scuffs (the swing foot touching the belt before its heel strike) per stride, the
    /// feet's mean.
    pub scuffs_per_stride: f64,
    /// Largest heel-strike deviation of hip and knee (deg).
    pub heel_strike_max_deviation_deg: [f64; 2],
    /// Largest recovery from a heel strike, hip and knee (s; NaN if none recovered).
    pub heel_strike_max_recovery_s: [f64; 2],
    /// Heel strikes not recovered within the follow-up, hip and knee.
    pub heel_strikes_unrecovered: [usize; 2],
    /// Whether the patient walked (`pma_leg::verdict`).
    pub walking: bool,
    /// When the trainer's safety stopped a collapse (s), if it did.
    pub collapse_s: Option<f64>,
}

impl TreadmillRow {
    /// The row of a run's treadmill figures: over every foot, the mean of each foot's
    /// figure (tracking, loading, stance, slip) and the worst of the heel strikes.
    fn of(t: &pma_leg::TreadmillReport, verdict: Option<&pma_leg::WalkingVerdict>) -> Self {
        let feet: Vec<&pma_leg::FootReport> = t.feet.values().collect();
        let mean = |f: &dyn Fn(&pma_leg::FootReport) -> f64| {
            feet.iter().map(|r| f(r)).sum::<f64>() / feet.len().max(1) as f64
        };
        let phases = |j: &str| {
            [0, 1].map(|k| {
                mean(&|r| {
                    r.tracking
                        .get(j)
                        .map_or(f64::NAN, |p| [p.stance_rms_deg, p.swing_rms_deg][k])
                })
            })
        };
        let strikes = |f: fn(&pma_leg::metrics::HeelStrikeStats) -> f64| {
            ["hip", "knee"].map(|j| {
                feet.iter()
                    .filter_map(|r| r.heel_strikes.get(j).map(f))
                    .fold(f64::NAN, f64::max)
            })
        };
        Self {
            hip_stance_swing_rms_deg: phases("hip"),
            knee_stance_swing_rms_deg: phases("knee"),
            peak_grf_bw: mean(&|r| r.peak_grf_bw.mean),
            loading_rate_bw_s: mean(&|r| r.loading_rate_bw_s.mean),
            stance_fraction: [
                mean(&|r| r.stance_fraction.mean),
                mean(&|r| r.reference_stance_fraction),
            ],
            slip_per_stride_m: mean(&|r| r.slip_per_stride_m.mean),
            scuffs_per_stride: mean(&|r| r.scuffs as f64 / r.strides.max(1) as f64),
            heel_strike_max_deviation_deg: strikes(|h| h.deviation_deg.max),
            heel_strike_max_recovery_s: strikes(|h| h.recovery_s.max),
            heel_strikes_unrecovered: ["hip", "knee"].map(|j| {
                feet.iter()
                    .filter_map(|r| r.heel_strikes.get(j))
                    .map(|h| h.not_recovered)
                    .sum()
            }),
            walking: verdict.is_some_and(|v| v.walking),
            collapse_s: verdict.and_then(|v| v.collapse.as_ref()).map(|c| c.t_s),
        }
    }
}

impl CompareRow {
    /// The row of `report`, a run of `controller`.
    pub fn of(report: &LegReport, controller: &str) -> Self {
        let rms = |j: &str| report.joint_rms_deg(j);
        let spasms = &report.spasms;
        // `None` where there is nothing to take the largest of (no spasm, none recovered).
        let fold = |f: fn(&pma_leg::SpasmReport) -> Option<f64>| {
            spasms.iter().filter_map(f).reduce(f64::max)
        };
        let muscles = report.safety.muscles.values();
        Self {
            scenario: report.scenario.clone(),
            controller: controller.to_owned(),
            hip_rms_deg: rms("hip"),
            knee_rms_deg: rms("knee"),
            spasms: spasms.len(),
            spasm_mean_deviation_deg: (!spasms.is_empty()).then(|| {
                spasms.iter().map(|s| s.peak_deviation_deg).sum::<f64>() / spasms.len() as f64
            }),
            spasm_max_deviation_deg: fold(|s| Some(s.peak_deviation_deg)),
            spasm_max_recovery_s: fold(|s| s.recovery_s),
            spasms_unrecovered: spasms
                .iter()
                .filter(|s| s.recovery_s.is_none() && !s.overlapped)
                .count(),
            spasms_overlapped: spasms.iter().filter(|s| s.overlapped).count(),
            spasm_peak_pressure_rate_bar_s: fold(|s| Some(s.peak_pressure_rate_bar_s)),
            peak_pressure_rate_bar_s: muscles
                .clone()
                .map(|m| m.peak_pressure_rate_bar_s)
                .fold(0.0, f64::max),
            command_variation_bar_per_s: report.command_variation_bar_per_s,
            peak_force_over_rated: muscles
                .clone()
                .map(|m| m.peak_over_rated)
                .fold(0.0, f64::max),
            valve_saturated_s: muscles.clone().map(|m| m.valve_saturated_s).sum(),
            time_outside_limits_s: report
                .safety
                .joints
                .values()
                .map(|l| l.time_outside_s)
                .sum(),
            time_over_rated_s: report
                .safety
                .muscles
                .values()
                .map(|m| m.time_over_rated_s)
                .sum(),
            min_force_margin_n: report
                .safety
                .muscles
                .values()
                .map(|m| m.margin_n)
                .fold(f64::INFINITY, f64::min),
            time_beyond_normal_range_s: report
                .safety
                .joints
                .values()
                .map(|l| l.time_beyond_normal_range_s)
                .sum(),
            treadmill: report
                .treadmill
                .as_ref()
                .map(|t| TreadmillRow::of(t, report.walking.as_ref())),
            finite: report.finite,
        }
    }
}

/// Runs every scenario with its controllers (`controllers[i]` on `scenarios[i]`) for `duration_s`, in parallel
/// on rayon's pool (the caller's `install` sets its size); rows in scenario-major order,
/// the same for any thread count. `progress` counts the runs done (for a progress bar).
pub fn compare(
    scenarios: &[LoadedScenario],
    controllers: &[Vec<ControllerConfig>],
    duration_s: f64,
    progress: Option<&std::sync::atomic::AtomicUsize>,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Vec<CompareRow>, LegError> {
    let pairs: Vec<(&LoadedScenario, &ControllerConfig)> = scenarios
        .iter()
        .zip(controllers)
        .flat_map(|(s, cs)| cs.iter().map(move |c| (s, c)))
        .collect();
    pairs
        .par_iter()
        .map(|(loaded, config)| {
            let mut sim = LegSim::with_controller(loaded, config)?;
            let settings = sim.settings(duration_s)?.with_stop_flag(stop);
            // A patient who collapses is a row (the verdict says so); another fault fails.
            let report = match sim.run_until_fault(&settings, &mut ())? {
                (report, None) => report,
                (report, Some(f)) if f.name == "collapse" => report,
                (_, Some(f)) => return Err(LegError::Supervisor(f.message)),
            };
            if let Some(n) = progress {
                n.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            Ok(CompareRow::of(&report, &config.kind().to_string()))
        })
        .collect()
}
