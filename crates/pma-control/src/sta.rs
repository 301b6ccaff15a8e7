use crate::command::CommandState;
use crate::{
    CommandLimits, ControlOutput, Controller, Diagnostics, KinematicObserver, Measurement,
    NominalModel, RefSample,
};

crate::gain_table! {
    /// Gains of the super-twisting algorithm on `s = e' + c1 e`:
    /// `s' = -k1 |s|^(1/2) sgn(s) + w`, `w' = -k2 sgn(s)`, on top of the nominal model's
    /// equivalent control (as NDO-SMC and APRC-NDO, it uses Table I).
    pub struct StaGains {
        /// Sliding surface `c1` (1/s).
        c1_per_s: Positive, Log(1.0, 1e4);
        /// Proportional STA gain `k1` (m^0.5 / s^1.5).
        k1: NonNegative, Log(1e-2, 1e2);
        /// Integral STA gain `k2` (m/s^3).
        k2: NonNegative, Log(1e-2, 1e4);
        /// Kinematic observer bandwidth (rad/s).
        estimator_bandwidth_rad_s: Positive, Log(50.0, 1000.0);
    }
}

impl Default for StaGains {
    fn default() -> Self {
        crate::config::tuned::STA
    }
}

/// Super-twisting sliding mode control (Levant), integral term by forward Euler.
#[derive(Debug, Clone)]
pub struct SuperTwisting {
    gains: StaGains,
    model: NominalModel,
    limits: CommandLimits,
    observer: KinematicObserver,
    w: f64,
    cmd: CommandState,
}

impl SuperTwisting {
    /// STA on the nominal model.
    pub fn new(gains: StaGains, model: NominalModel, limits: CommandLimits) -> Self {
        Self {
            gains,
            model,
            limits,
            observer: KinematicObserver::new(gains.estimator_bandwidth_rad_s),
            w: 0.0,
            cmd: CommandState::at_rest(&model, &limits, 0.0),
        }
    }
}

impl Controller for SuperTwisting {
    fn name(&self) -> &'static str {
        "sta"
    }

    fn reset(&mut self, measurement: Measurement, _reference: RefSample) {
        self.observer.reset(measurement.position_m);
        self.w = 0.0;
        self.cmd = CommandState::at_rest(&self.model, &self.limits, measurement.position_m);
    }

    fn applied(&mut self, applied_pa: f64) {
        self.cmd.applied(applied_pa);
    }

    fn update(&mut self, r: &RefSample, m: &Measurement, dt: f64) -> ControlOutput {
        self.observer.update(m.position_m, dt);
        let (x, v) = (self.observer.position(), self.observer.velocity());
        let g = &self.gains;
        let e = r.position_m - x;
        let s = (r.velocity_m_s - v) + g.c1_per_s * e;
        let twist = g.k1 * s.abs().sqrt() * s.signum();
        let accel = r.acceleration_m_s2 + g.c1_per_s * (r.velocity_m_s - v) + twist + self.w;
        let u = self
            .cmd
            .invert(&self.limits, &self.model, (x, v), accel, dt);
        let push = s.signum();
        if !self.cmd.saturation.blocks(push) {
            self.w += dt * g.k2 * push;
        }
        ControlOutput {
            pressure_cmd_pa: u,
            diagnostics: Diagnostics {
                s_q: s,
                disturbance_hat: -self.w,
                velocity_m_s: v,
                ..Diagnostics::NONE
            },
        }
    }
}
