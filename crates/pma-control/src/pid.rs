use crate::command::CommandState;
use crate::{
    CommandLimits, ControlOutput, Controller, Diagnostics, KinematicObserver, Measurement,
    NominalModel, RefSample,
};

crate::gain_table! {
    /// Gains of the PID baseline: `u = bias + Kp e + Ki ∫e + Kd e'`.
    pub struct PidGains {
        /// Proportional gain (Pa/m).
        kp_pa_per_m: NonNegative, Log(1e5, 1e11) => PressurePer(1e-6);
        /// Integral gain (Pa/(m s)).
        ki_pa_per_m_s: NonNegative, Log(1e5, 1e12) => PressurePer(1e-9);
        /// Derivative gain on the velocity error (Pa s/m).
        kd_pa_s_per_m: NonNegative, Log(1e2, 1e7) => PressurePer(1e-3);
        /// Constant bias pressure (Pa), for a PD (`ki_pa_per_m_s = 0`) only: with an
        /// integral the bumpless start puts the resting pressure into it, whatever the
        /// bias, so a bias there would have no effect and is refused.
        bias_pa: NonNegative => Pressure;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Why a bias with an integral is refused: the bumpless start puts the resting
    /// pressure into the integral whatever the bias, so two PIDs that differ only in their
    /// bias command the same pressures (to rounding) on the same readings.
    #[test]
    fn a_bias_with_an_integral_has_no_effect() {
        let limits = CommandLimits::default();
        let model = NominalModel::paper();
        let gains = PidGains {
            bias_pa: 0.0,
            ..PidGains::default()
        };
        let mut plain = Pid::new(gains, model, limits);
        let mut biased = Pid::new(
            PidGains {
                bias_pa: 1.5e5,
                ..gains
            },
            model,
            limits,
        );
        let dt = 1e-3;
        let at = |k: usize| {
            let t = k as f64 * dt;
            (
                RefSample {
                    position_m: 0.015 + 0.015 * (0.5 * std::f64::consts::PI * t).sin(),
                    velocity_m_s: 0.0,
                    acceleration_m_s2: 0.0,
                },
                Measurement {
                    position_m: 0.012 + 0.014 * (0.5 * std::f64::consts::PI * (t - 0.05)).sin(),
                },
            )
        };
        let (r0, m0) = at(0);
        plain.reset(m0, r0);
        biased.reset(m0, r0);
        let mut largest = 0.0f64;
        for k in 1..4000 {
            let (r, m) = at(k);
            let a = plain.update(&r, &m, dt).pressure_cmd_pa;
            let b = biased.update(&r, &m, dt).pressure_cmd_pa;
            plain.applied(a);
            biased.applied(b);
            largest = largest.max((a - b).abs());
        }
        assert!(largest < 1e-3, "the bias moved a command by {largest} Pa");
    }
}
