//! The single-muscle task (one controller tracking one reference) and its tracking
//! metrics: what the bench, the virtual rig and the real rig all run.
use crate::{ControlOutput, Controller, Measurement, Metrics, RefSample, Reference, TrackingStats};
use pma_loop::{Backend, Period, Recorder, Start, Task};

/// One controller tracking one reference: the single-muscle [`Task`].
pub struct MuscleTask<'r> {
    controller: Box<dyn Controller>,
    reference: &'r dyn Reference,
}

/// One period of a [`MuscleTask`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MuscleStep {
    /// The reference sample the controller tracked.
    pub reference: RefSample,
    /// Its output (command and internal states).
    pub control: ControlOutput,
}

impl<'r> MuscleTask<'r> {
    /// `controller` tracking `reference`.
    pub fn new(controller: Box<dyn Controller>, reference: &'r dyn Reference) -> Self {
        Self {
            controller,
            reference,
        }
    }

    /// The controller.
    pub fn controller(&self) -> &dyn Controller {
        self.controller.as_ref()
    }
}

impl Task for MuscleTask<'_> {
    type Reading = Measurement;
    type Command = f64;
    type Output = MuscleStep;

    /// Resets the controller on the first reading; it acts from the first period on.
    fn start(
        &mut self,
        t_s: f64,
        reading: &Measurement,
        _resting: &f64,
        _period_s: f64,
    ) -> Option<MuscleStep> {
        self.controller.reset(*reading, self.reference.sample(t_s));
        None
    }

    fn update(&mut self, t_s: f64, reading: &Measurement, dt_s: f64) -> MuscleStep {
        let reference = self.reference.sample(t_s);
        let control = self.controller.update(&reference, reading, dt_s);
        MuscleStep { reference, control }
    }

    fn command(output: &MuscleStep) -> f64 {
        output.control.pressure_cmd_pa
    }

    fn applied(&mut self, written: &f64) {
        self.controller.applied(*written);
    }
}

/// Tracking figures of eqs. (51)-(53) plus command activity, accumulated period by period
/// without allocation. The caller decides which position counts (the true one in
/// simulation, the measured one on a rig).
#[derive(Debug, Clone, Copy)]
pub struct TrackingMetrics {
    metrics: Metrics,
    x_a_m: f64,
    variation_pa: f64,
    previous_command_pa: f64,
    finite: bool,
}

/// What [`TrackingMetrics`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackingSummary {
    /// MAE, IAE, RTE, RMS.
    pub stats: TrackingStats,
    /// `x_a` of eq. (53) used for RTE (m).
    pub x_a_m: f64,
    /// Total variation of the command per second of run (Pa/s).
    pub command_variation_pa_per_s: f64,
    /// Whether every position and command stayed finite.
    pub finite: bool,
}

impl TrackingMetrics {
    /// Starts with the command held at the start (the first variation is measured from it).
    pub fn new(initial_command_pa: f64) -> Self {
        Self {
            metrics: Metrics::new(),
            x_a_m: 0.0,
            variation_pa: 0.0,
            previous_command_pa: initial_command_pa,
            finite: true,
        }
    }

    /// One period: the reference, the position it is compared with, the new command.
    pub fn push(&mut self, reference_m: f64, position_m: f64, command_pa: f64) {
        self.variation_pa += (command_pa - self.previous_command_pa).abs();
        self.previous_command_pa = command_pa;
        self.finite &= position_m.is_finite() && command_pa.is_finite();
        self.metrics.push(reference_m - position_m);
        self.x_a_m = self.x_a_m.max(reference_m.abs());
    }

    /// The figures over `duration_s`; `x_a_m` overrides the largest reference position.
    pub fn summary(&self, duration_s: f64, x_a_m: Option<f64>) -> TrackingSummary {
        let x_a = x_a_m.unwrap_or(self.x_a_m);
        TrackingSummary {
            stats: self.metrics.finish(x_a),
            x_a_m: x_a,
            command_variation_pa_per_s: self.variation_pa / duration_s,
            finite: self.finite,
        }
    }
}

/// Which position a run's tracking is measured on: the true one in a simulation, the
/// reading on a rig (which knows nothing else).
pub type PositionOf<B> = fn(&<B as Backend>::Reading, &<B as Backend>::Truth) -> f64;

/// The one definition of a single-muscle run's tracking figures, as a recorder: eqs.
/// (51)-(53) on the position `position` picks, and the variation of the command as
/// applied (after the backend's clamp or a supervisor's limits).
pub struct Tracking<B: Backend> {
    metrics: TrackingMetrics,
    position: PositionOf<B>,
}

impl<B: Backend> Tracking<B> {
    /// Tracking measured on `position`.
    pub fn new(position: PositionOf<B>) -> Self {
        Self {
            metrics: TrackingMetrics::new(0.0),
            position,
        }
    }

    /// The figures over `ran_s` (the run's [`pma_loop::Outcome::ran_s`]); `x_a_m`
    /// overrides the largest reference position.
    pub fn summary(&self, ran_s: f64, x_a_m: Option<f64>) -> TrackingSummary {
        self.metrics.summary(ran_s, x_a_m)
    }
}

impl<B: Backend<Command = f64>> Recorder<B, MuscleStep> for Tracking<B> {
    fn start(&mut self, s: &Start<'_, B>) {
        self.metrics = TrackingMetrics::new(*s.held);
    }
    fn record(&mut self, p: &Period<'_, B, MuscleStep>) {
        self.metrics.push(
            p.output.reference.position_m,
            (self.position)(p.reading, p.truth),
            *p.written,
        );
        self.metrics.finite &= p.output.control.pressure_cmd_pa.is_finite();
    }
}
