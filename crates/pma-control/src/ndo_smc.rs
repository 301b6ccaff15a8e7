use crate::command::CommandState;
use crate::{
    CommandLimits, ControlOutput, Controller, Diagnostics, DisturbanceObserver, KinematicObserver,
    Measurement, NominalModel, RefSample,
};

crate::gain_table! {
    /// Gains of NDO-SMC: `s = e' + c1 e + c2 ∫e`, `e = x_d - x`, reaching law
    /// `s' = -k s - eta sat(s/phi)` (the paper replaces `sign` by `sat`), disturbance from the
    /// same observer as APRC-NDO.
    pub struct NdoSmcGains {
        /// Sliding surface `c1` (1/s).
        c1_per_s: Positive, Log(1.0, 1e4);
        /// Sliding surface integral weight `c2` (1/s^2).
        c2_per_s2: NonNegative, Log(1e-1, 1e5);
        /// Linear reaching gain `k` (1/s).
        k_per_s: NonNegative, Log(1e-1, 1e3);
        /// Switching gain `eta` (m/s^2).
        eta_m_s2: NonNegative, Log(1e-2, 1e2);
        /// Boundary layer `phi` of `sat` (m/s).
        phi_m_s: Positive, Log(1e-4, 1e-1);
        /// Disturbance observer gain (1/s).
        kappa_per_s: Positive, Log(10.0, 2e4);
        /// Kinematic observer bandwidth (rad/s).
        estimator_bandwidth_rad_s: Positive, Log(50.0, 1000.0);
    }
}

impl Default for NdoSmcGains {
    fn default() -> Self {
        crate::config::tuned::NDO_SMC
    }
}

/// Disturbance-observer-based sliding mode control with a boundary layer.
#[derive(Debug, Clone)]
pub struct NdoSmc {
    gains: NdoSmcGains,
    model: NominalModel,
    limits: CommandLimits,
    observer: KinematicObserver,
    ndo: DisturbanceObserver,
    int_error: f64,
    cmd: CommandState,
}

impl NdoSmc {
    /// NDO-SMC on the nominal model.
    pub fn new(gains: NdoSmcGains, model: NominalModel, limits: CommandLimits) -> Self {
        Self {
            gains,
            model,
            limits,
            observer: KinematicObserver::new(gains.estimator_bandwidth_rad_s),
            ndo: DisturbanceObserver::new(gains.kappa_per_s),
            int_error: 0.0,
            cmd: CommandState::at_rest(&model, &limits, 0.0),
        }
    }
}

impl Controller for NdoSmc {
    fn name(&self) -> &'static str {
        "ndo-smc"
    }

    fn reset(&mut self, measurement: Measurement, _reference: RefSample) {
        self.observer.reset(measurement.position_m);
        self.ndo.reset();
        self.int_error = 0.0;
        self.cmd = CommandState::at_rest(&self.model, &self.limits, measurement.position_m);
    }

    fn applied(&mut self, applied_pa: f64) {
        self.cmd.applied(applied_pa);
    }

    fn pressure_sensed(&mut self, pressure_pa: f64) {
        self.cmd.sensed(pressure_pa);
    }

    fn update(&mut self, r: &RefSample, m: &Measurement, dt: f64) -> ControlOutput {
        self.observer.update(m.position_m, dt);
        let (x, v, a) = self.observer.state();
        let tau_hat = self.ndo.update(
            &self.model,
            x,
            v,
            a,
            self.cmd.pressure_hat,
            self.cmd.mode,
            dt,
        );
        let g = &self.gains;
        let e = r.position_m - x;
        if !self.cmd.saturation.blocks(e) {
            self.int_error += dt * e;
        }
        let s = (r.velocity_m_s - v) + g.c1_per_s * e + g.c2_per_s2 * self.int_error;
        let sat = (s / g.phi_m_s).clamp(-1.0, 1.0);
        let accel = r.acceleration_m_s2 + g.c1_per_s * (r.velocity_m_s - v) + g.c2_per_s2 * e
            - tau_hat
            + g.k_per_s * s
            + g.eta_m_s2 * sat;
        let u = self
            .cmd
            .invert(&self.limits, &self.model, (x, v), accel, dt);
        ControlOutput {
            pressure_cmd_pa: u,
            diagnostics: Diagnostics {
                s_q: s,
                disturbance_hat: tau_hat,
                velocity_m_s: v,
                ..Diagnostics::NONE
            },
        }
    }
}
