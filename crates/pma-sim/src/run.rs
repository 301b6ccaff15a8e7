use crate::{MuscleBench, Plant, PlantConfig, SimError};
use pma_control::{
    build_controller, CommandLimits, Controller, ControllerConfig, Diagnostics, Metrics, Reference,
    TrackingStats,
};
use std::time::Instant;

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
    /// Rejects non-finite or non-positive durations and periods.
    pub fn validate(&self) -> Result<(), SimError> {
        for (name, value) in [("duration_s", self.duration_s), ("period_s", self.period_s)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(SimError::InvalidRun {
                    name,
                    value,
                    expected: "must be a finite number > 0",
                });
            }
        }
        Ok(())
    }

    /// Number of control periods.
    pub fn steps(&self) -> usize {
        (self.duration_s / self.period_s).round() as usize
    }
}

/// One logged control period.
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
    /// True pressure after the period (Pa).
    pub pressure_pa: f64,
    /// Muscle force after the period (N).
    pub force_n: f64,
    /// Controller states.
    pub diagnostics: Diagnostics,
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
}

/// Runs `controller` against `plant` for `spec`, calling `observe` each period.
///
/// Order in a period: the plant advances over `[t_{k-1}, t_k]` with the held command,
/// the sensor is read at `t_k`, the controller computes the next command. The error
/// `x_d(t_k) - x(t_k)` uses the true position.
pub fn run_loop(
    controller: &mut dyn Controller,
    plant: &mut dyn Plant,
    reference: &dyn Reference,
    spec: &RunSpec,
    mut observe: Option<&mut dyn FnMut(&Sample)>,
) -> Result<RunResult, SimError> {
    spec.validate()?;
    let dt = spec.period_s;
    let t0 = plant.time();
    controller.reset(plant.measure(), reference.sample(t0));
    let mut u = plant.pressure();
    let mut metrics = Metrics::new();
    let mut x_a: f64 = 0.0;
    let mut finite = true;
    let mut variation = 0.0;
    let start = Instant::now();
    for k in 1..=spec.steps() {
        plant.apply(u, dt);
        let t = t0 + k as f64 * dt;
        let meas = plant.measure();
        let r = reference.sample(t);
        let out = controller.update(&r, &meas, dt);
        variation += (out.pressure_cmd_pa - u).abs();
        u = out.pressure_cmd_pa;
        let x = plant.position();
        finite &= x.is_finite() && u.is_finite();
        metrics.push(r.position_m - x);
        x_a = x_a.max(r.position_m.abs());
        if let Some(f) = observe.as_mut() {
            f(&Sample {
                t_s: t,
                reference_m: r.position_m,
                position_m: x,
                measured_m: meas.position_m,
                pressure_cmd_pa: u,
                pressure_pa: plant.pressure(),
                force_n: plant.force(),
                diagnostics: out.diagnostics,
            });
        }
    }
    let wall = start.elapsed().as_secs_f64();
    let x_a = spec.x_a_m.unwrap_or(x_a);
    Ok(RunResult {
        controller: controller.name(),
        stats: metrics.finish(x_a),
        x_a_m: x_a,
        command_variation_pa_per_s: variation / spec.duration_s,
        real_time_factor: spec.duration_s / wall.max(1e-12),
        finite,
    })
}

/// Builds the controller and the bench (at rest on the reference's start) and runs them.
pub fn run_single(
    config: &ControllerConfig,
    plant: &PlantConfig,
    reference: &dyn Reference,
    spec: &RunSpec,
    observe: Option<&mut dyn FnMut(&Sample)>,
) -> Result<RunResult, SimError> {
    let limits = CommandLimits {
        min_pa: 0.0,
        max_pa: plant.valve.pressure_max_pa,
    };
    let mut controller = build_controller(config, plant.nominal_model(), limits)?;
    let mut bench = MuscleBench::at_rest(plant, reference.sample(0.0).position_m)?;
    run_loop(controller.as_mut(), &mut bench, reference, spec, observe)
}
