use crate::{BenchState, MuscleBench, PlantConfig, SimError};
use pma_control::{
    build_controller, CommandLimits, ControllerConfig, Diagnostics, MuscleStep, MuscleTask,
    Reference, Tracking, TrackingStats,
};
use pma_loop::{LoopSettings, Period, Recorder, Schema, Signals};
use pma_model::Invalid;
use std::sync::atomic::AtomicBool;

/// Shortest and longest control period a user may ask for (s).
pub const PERIOD_RANGE_S: (f64, f64) = (1e-4, 1e-2);
/// Fewest control periods of a run whose figures are reported.
pub const MIN_PERIODS: u64 = 100;

/// Duration and period of a closed-loop run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSpec {
    /// Simulated time (s).
    pub duration_s: f64,
    /// Control period (s).
    pub period_s: f64,
    /// Maximum running displacement `x_a` of eq. (53) (m); `None` takes the largest
    /// reference position of the run (30 mm for the paper's references).
    pub x_a_m: Option<f64>,
}

impl Default for RunSpec {
    /// 20 s at the paper's 1 ms period.
    fn default() -> Self {
        Self {
            duration_s: 20.0,
            period_s: 1e-3,
            x_a_m: None,
        }
    }
}

impl RunSpec {
    /// The loop settings: rejects non-finite or non-positive durations and periods, and
    /// runs shorter than one period.
    pub fn settings(&self) -> Result<LoopSettings<'static>, SimError> {
        let settings = LoopSettings::new(self.duration_s)?;
        settings.periods(self.period_s)?;
        Ok(settings)
    }

    /// The checks of a run a user describes (a sweep file): a period the controllers are
    /// discretised for and at least [`MIN_PERIODS`] of them, so that the figures describe
    /// tracking rather than a few samples.
    pub fn validate(&self) -> Result<LoopSettings<'static>, SimError> {
        if !(self.period_s >= PERIOD_RANGE_S.0 && self.period_s <= PERIOD_RANGE_S.1) {
            return Err(Invalid::new(
                "period_s",
                self.period_s,
                "must be 0.0001 to 0.01 s (the controllers are discretised for 0.1-10 ms; the paper ran at 1 ms)",
            )
            .into());
        }
        let settings = self.settings()?;
        if settings.periods(self.period_s)? < MIN_PERIODS {
            return Err(Invalid::new(
                "duration_s",
                self.duration_s,
                "must cover at least 100 control periods",
            )
            .into());
        }
        Ok(settings)
    }

    /// Number of control periods.
    pub fn periods(&self) -> Result<u64, SimError> {
        Ok(self.settings()?.periods(self.period_s)?)
    }
}

/// One logged control period of the bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time (s).
    pub t_s: f64,
    /// Reference `x_d` (m).
    pub reference_m: f64,
    /// True contraction (m).
    pub position_m: f64,
    /// Sensor reading (m).
    pub measured_m: f64,
    /// Command (Pa).
    pub pressure_cmd_pa: f64,
    /// True pressure at the reading (Pa).
    pub pressure_pa: f64,
    /// Muscle force at the reading (N).
    pub force_n: f64,
    /// Controller states.
    pub diagnostics: Diagnostics,
}

impl Sample {
    /// The bench's view of one loop period.
    pub fn of(p: &Period<'_, MuscleBench, MuscleStep>) -> Self {
        let s: &BenchState = p.truth;
        Sample {
            t_s: p.t_s,
            reference_m: p.output.reference.position_m,
            position_m: s.position_m,
            measured_m: p.reading.position_m,
            pressure_cmd_pa: p.output.control.pressure_cmd_pa,
            pressure_pa: s.pressure_pa,
            force_n: s.force_n,
            diagnostics: p.output.control.diagnostics,
        }
    }
}

impl Sample {
    /// The bench's channels (after the time), as the CSV and Rerun show them.
    pub fn schema() -> Schema {
        let mut s = Schema::new();
        let g = "muscles/muscle";
        s.push(g, "reference_m", "reference x_d (m)")
            .push(g, "position_m", "true contraction (m)")
            .push(g, "pressure_cmd_pa", "pressure command (Pa)")
            .push(g, "pressure_pa", "pressure in the muscle (Pa)")
            .push(g, "proxy_m", "proxy position (m)")
            .push(g, "s_p", "S_p, eq. (4) (m/s)")
            .push(g, "s_q", "S_q, eq. (3) (m/s)")
            .push(g, "gain_hat", "adaptive gain Gamma_hat, eq. (10)")
            .push(
                g,
                "disturbance_hat",
                "disturbance estimate, eq. (37) (m/s^2)",
            )
            .push(g, "measured_m", "the sensor's reading (m)")
            .push(g, "force_n", "muscle force (N)")
            .push(
                g,
                "velocity_estimate_m_s",
                "the controller's velocity estimate (m/s)",
            );
        s
    }
}

impl Signals for Sample {
    fn values(&self, out: &mut [f64]) {
        let d = &self.diagnostics;
        out.copy_from_slice(&[
            self.reference_m,
            self.position_m,
            self.pressure_cmd_pa,
            self.pressure_pa,
            d.proxy_position_m,
            d.s_p,
            d.s_q,
            d.gain_hat,
            d.disturbance_hat,
            self.measured_m,
            self.force_n,
            d.velocity_m_s,
        ]);
    }
}

/// A recorder that hands every period to a closure as a [`Sample`].
pub struct Samples<F>(pub F);

impl<F: FnMut(&Sample)> Recorder<MuscleBench, MuscleStep> for Samples<F> {
    fn record(&mut self, p: &Period<'_, MuscleBench, MuscleStep>) {
        (self.0)(&Sample::of(p));
    }
}

/// Outcome of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// Controller name.
    pub controller: &'static str,
    /// Metrics of eqs. (51)-(53) on the true position.
    pub stats: TrackingStats,
    /// `x_a` used for RTE (m).
    pub x_a_m: f64,
    /// Total variation of the pressure command per simulated second (Pa/s): how much the
    /// valve is asked to move. A smooth command for the paper's sine needs ~0.4 bar/s;
    /// chattering shows up here long before it shows in the tracking error.
    pub command_variation_pa_per_s: f64,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
    /// Control periods run.
    pub periods: u64,
    /// Whether the run was stopped early (the stop flag).
    pub interrupted: bool,
}

/// Builds the controller and the bench (at rest on the reference's start) and runs them
/// through the closed loop of `pma-loop`, `recorder` observing every period (`&mut ()`
/// for none, [`Samples`] for a closure).
///
/// Order in a period: the bench advances over `[t_{k-1}, t_k]` with the held command, the
/// sensor is read at `t_k`, the controller computes the next command. The error
/// `x_d(t_k) - x(t_k)` uses the true position.
pub fn run_single<R: Recorder<MuscleBench, MuscleStep>>(
    config: &ControllerConfig,
    plant: &PlantConfig,
    reference: &dyn Reference,
    spec: &RunSpec,
    recorder: &mut R,
) -> Result<RunResult, SimError> {
    run_single_until(
        config,
        plant,
        reference,
        spec,
        &AtomicBool::new(false),
        recorder,
    )
}

/// [`run_single`], ended early (and reported `interrupted`) once `stop` is raised.
pub fn run_single_until<R: Recorder<MuscleBench, MuscleStep>>(
    config: &ControllerConfig,
    plant: &PlantConfig,
    reference: &dyn Reference,
    spec: &RunSpec,
    stop: &AtomicBool,
    recorder: &mut R,
) -> Result<RunResult, SimError> {
    let settings = spec.settings()?.with_stop_flag(stop);
    let limits = CommandLimits {
        min_pa: 0.0,
        max_pa: plant.valve.pressure_max_pa,
    };
    let controller = build_controller(config, plant.nominal_model(), limits)?;
    let name = controller.name();
    let mut bench =
        MuscleBench::at_rest(plant, reference.sample(0.0).position_m)?.with_period(spec.period_s);
    let mut task = MuscleTask::new(controller, reference);
    let mut tracking = Tracking::<MuscleBench>::new(|_, truth| truth.position_m);
    let outcome = pma_loop::run(
        &mut bench,
        &mut task,
        &mut (&mut tracking, recorder),
        &settings,
    )?;
    let outcome = match outcome.into_result() {
        Ok(o) => o,
        Err(never) => match never {},
    };
    let interrupted = matches!(outcome.end, pma_loop::End::Stopped);
    let ran_s = outcome.ran_s;
    let summary = tracking.summary(ran_s, spec.x_a_m);
    Ok(RunResult {
        controller: name,
        stats: summary.stats,
        x_a_m: summary.x_a_m,
        command_variation_pa_per_s: summary.command_variation_pa_per_s,
        real_time_factor: ran_s / outcome.wall_s.max(1e-12),
        finite: summary.finite,
        periods: outcome.periods,
        interrupted,
    })
}
