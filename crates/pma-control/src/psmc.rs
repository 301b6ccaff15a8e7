use crate::command::CommandState;
use crate::{
    implicit_sign_solve, CommandLimits, ControlOutput, Controller, Diagnostics, KinematicObserver,
    Measurement, NominalModel, RefSample,
};

crate::gain_table! {
    /// Gains of PSMC. Kikuuwe et al. (2010) is model-free: a PID couples a massless proxy to
    /// the object and the proxy slides on `sigma = (x_d - p) + H (x_d' - p')` with force bound
    /// `F`. A muscle needs a positive pressure to hold any load, so the PID force is added to
    /// a constant bias pressure (the mid-range of the holding pressures), and `F` bounds the
    /// deviation from that bias.
    pub struct PsmcGains {
        /// Proportional gain (Pa/m).
        kp_pa_per_m: NonNegative, Log(1e5, 1e11) => PressurePer(1e-6);
        /// Integral gain (Pa/(m s)).
        ki_pa_per_m_s: NonNegative, Log(1e5, 1e12) => PressurePer(1e-9);
        /// Derivative gain (Pa s/m).
        kd_pa_s_per_m: NonNegative, Log(1e2, 1e7) => PressurePer(1e-3);
        /// Sliding-surface time constant `H` (s).
        h_s: NonNegative, Log(1e-3, 1.0);
        /// Force bound `F` (Pa).
        force_max_pa: Positive, Log(1e3, 6e5);
        /// Bias pressure (Pa).
        bias_pa: NonNegative, Lin(0.0, 2e5) => Pressure;
        /// Kinematic observer bandwidth (rad/s).
        estimator_bandwidth_rad_s: Positive, Log(50.0, 1000.0);
    }
}

impl Default for PsmcGains {
    fn default() -> Self {
        crate::config::tuned::PSMC
    }
}

/// Proxy-based sliding mode control (Kikuuwe et al., IEEE T-RO 26(4), 2010) in its
/// discrete-time form: backward Euler for the proxy, the set-valued `sgn` solved in closed
/// form so that the proxy sticks on `sigma = 0` while `|f| < F`.
#[derive(Debug, Clone)]
pub struct Psmc {
    gains: PsmcGains,
    model: NominalModel,
    limits: CommandLimits,
    observer: KinematicObserver,
    p: f64,
    int_proxy_object: f64,
    cmd: CommandState,
}

impl Psmc {
    /// PSMC; `model` is used only to start from the resting pressure.
    pub fn new(gains: PsmcGains, model: NominalModel, limits: CommandLimits) -> Self {
        Self {
            gains,
            model,
            limits,
            observer: KinematicObserver::new(gains.estimator_bandwidth_rad_s),
            p: 0.0,
            int_proxy_object: 0.0,
            cmd: CommandState::at_rest(&model, &limits, 0.0),
        }
    }
}

impl Controller for Psmc {
    fn name(&self) -> &'static str {
        "psmc"
    }

    fn reset(&mut self, measurement: Measurement, reference: RefSample) {
        self.observer.reset(measurement.position_m);
        self.p = reference.position_m;
        self.cmd = CommandState::at_rest(&self.model, &self.limits, measurement.position_m);
        // Start the integral where the resting pressure needs it, so the first command
        // does not drop the load.
        self.int_proxy_object = if self.gains.ki_pa_per_m_s > 0.0 {
            (self.cmd.u_prev - self.gains.bias_pa)
                .clamp(-self.gains.force_max_pa, self.gains.force_max_pa)
                / self.gains.ki_pa_per_m_s
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
        let hold = self.cmd.saturation.blocks(self.p - x);
        let t_int = if hold { 0.0 } else { dt };
        let p0 = self.p;
        let sigma0 = (r.position_m - p0) + g.h_s * r.velocity_m_s;
        let f0 = g.kp_pa_per_m * (p0 - x)
            + g.ki_pa_per_m_s * (self.int_proxy_object + t_int * (p0 - x))
            - g.kd_pa_s_per_m * v;
        let sigma_slope = 1.0 + g.h_s / dt;
        let lambda = g.kp_pa_per_m + g.ki_pa_per_m_s * t_int + g.kd_pa_s_per_m / dt;
        let s_star = sigma0 + sigma_slope * f0 / lambda;
        let sigma = implicit_sign_solve(s_star, lambda / sigma_slope, g.force_max_pa);
        let p = p0 - (sigma - sigma0) / sigma_slope;
        let f = f0 - lambda * (sigma - sigma0) / sigma_slope;
        self.int_proxy_object += t_int * (p - x);
        self.p = p;
        let u = self.cmd.apply(&self.limits, g.bias_pa + f);
        ControlOutput {
            pressure_cmd_pa: u,
            diagnostics: Diagnostics {
                proxy_position_m: p,
                s_p: sigma,
                velocity_m_s: v,
                ..Diagnostics::NONE
            },
        }
    }
}
