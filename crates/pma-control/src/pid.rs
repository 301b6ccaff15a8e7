use crate::command::CommandState;
use crate::{
    CommandLimits, ControlOutput, Controller, Diagnostics, KinematicObserver, Measurement,
    NominalModel, RefSample,
};

crate::gain_table! {
    /// Gains of the PID baseline: `u = bias + Kp e + Ki ∫e + Kd e'`.
    pub struct PidGains {
        /// Proportional gain (Pa/m).
        kp_pa_per_m: NonNegative, Log(1e5, 1e11);
        /// Integral gain (Pa/(m s)).
        ki_pa_per_m_s: NonNegative, Log(1e5, 1e12);
        /// Derivative gain on the velocity error (Pa s/m).
        kd_pa_s_per_m: NonNegative, Log(1e2, 1e7);
        /// Constant bias pressure (Pa).
        bias_pa: Finite, Lin(0.0, 2e5);
        /// Kinematic observer bandwidth (rad/s).
        estimator_bandwidth_rad_s: Positive, Log(50.0, 1000.0);
    }
}

impl Default for PidGains {
    fn default() -> Self {
        crate::config::tuned::PID
    }
}

/// PID with conditional-integration anti-windup; the derivative acts on the velocity
/// error from the kinematic observer (no derivative kick on reference steps beyond it).
#[derive(Debug, Clone)]
pub struct Pid {
    gains: PidGains,
    model: NominalModel,
    limits: CommandLimits,
    observer: KinematicObserver,
    int_error: f64,
    cmd: CommandState,
}

impl Pid {
    /// PID; `model` is used only to start from the resting pressure.
    pub fn new(gains: PidGains, model: NominalModel, limits: CommandLimits) -> Self {
        Self {
            gains,
            model,
            limits,
            observer: KinematicObserver::new(gains.estimator_bandwidth_rad_s),
            int_error: 0.0,
            cmd: CommandState::at_rest(&model, &limits, 0.0),
        }
    }
}

impl Controller for Pid {
    fn name(&self) -> &'static str {
        "pid"
    }

    fn reset(&mut self, measurement: Measurement, _reference: RefSample) {
        self.observer.reset(measurement.position_m);
        self.cmd = CommandState::at_rest(&self.model, &self.limits, measurement.position_m);
        // Bumpless start: the integral holds the resting pressure.
        self.int_error = if self.gains.ki_pa_per_m_s > 0.0 {
            (self.cmd.u_prev - self.gains.bias_pa) / self.gains.ki_pa_per_m_s
        } else {
            0.0
        };
    }

    fn applied(&mut self, applied_pa: f64) {
        self.cmd.applied(applied_pa);
    }

    fn update(&mut self, r: &RefSample, m: &Measurement, dt: f64) -> ControlOutput {
        self.observer.update(m.position_m, dt);
        let (x, v) = (self.observer.position(), self.observer.velocity());
        let g = &self.gains;
        let e = r.position_m - x;
        if !self.cmd.saturation.blocks(e) {
            self.int_error += dt * e;
        }
        let raw = g.bias_pa
            + g.kp_pa_per_m * e
            + g.ki_pa_per_m_s * self.int_error
            + g.kd_pa_s_per_m * (r.velocity_m_s - v);
        let u = self.cmd.apply(&self.limits, raw);
        ControlOutput {
            pressure_cmd_pa: u,
            diagnostics: Diagnostics {
                velocity_m_s: v,
                ..Diagnostics::NONE
            },
        }
    }
}
