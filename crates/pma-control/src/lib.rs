//! Controllers for a single pneumatic muscle, all behind one [`Controller`] trait:
//! APRC-NDO and APRC (Cao et al. 2020), PSMC (Kikuuwe et al. 2010), NDO-SMC with `sat`,
//! super-twisting (STA) and PID; plus the reference trajectories and metrics of the paper.
//!
//! Every controller receives the reference sample, the *measured position only* and the
//! period `dt`; velocity (and acceleration, for the disturbance observer) come from a
//! [`KinematicObserver`] inside the controller, so simulation and rig run the same code.
//!
//! ```
//! use pma_control::{build_controller, CommandLimits, ControllerConfig, Measurement,
//!                   NominalModel, Reference, SineReference};
//! let cfg = ControllerConfig::default(); // APRC-NDO with the paper's gains
//! let mut c = build_controller(&cfg, NominalModel::paper(), CommandLimits::default()).unwrap();
//! let r = SineReference::paper();
//! c.reset(Measurement { position_m: 0.015 }, r.sample(0.0));
//! let out = c.update(&r.sample(0.001), &Measurement { position_m: 0.015 }, 0.001);
//! assert!(out.pressure_cmd_pa >= 0.0 && out.pressure_cmd_pa <= 6.0e5);
//! ```
#![warn(missing_docs)]

mod aprc;
mod command;
mod config;
mod estimator;
mod excitation;
pub mod gains;
mod implicit;
mod metrics;
mod ndo;
mod ndo_smc;
mod nominal;
mod pid;
mod psmc;
mod reference;
#[cfg(feature = "serde")]
pub mod shipped;
mod sta;
pub mod supervisor;
mod task;
#[cfg(feature = "serde")]
pub mod text;

pub use aprc::{AprcGains, AprcNdo};
pub use config::{build_controller, ConfigError, ControllerConfig, ControllerKind};
pub use estimator::KinematicObserver;
pub use excitation::{Excitation, ExcitationError, ExcitationSpec};
pub use implicit::implicit_sign_solve;
pub use metrics::{nearest_rank, Metrics, TrackingStats};
pub use ndo::DisturbanceObserver;
pub use ndo_smc::{NdoSmc, NdoSmcGains};
pub use nominal::{
    NominalModel, NominalSpec, DEFAULT_MODE_SWITCH_DEADBAND_PA, DEFAULT_MODE_SWITCH_FRACTION,
};
pub use pid::{Pid, PidGains};
pub use psmc::{Psmc, PsmcGains};
pub use reference::{
    quintic_blend, ChirpReference, JumpReference, Reference, SineReference, SmoothStart, Trajectory,
};
pub use sta::{StaGains, SuperTwisting};
pub use supervisor::{
    Alarm, Channels, Fault, ReadingWindow, Supervised, SupervisorLimits, Watchdog,
};
pub use task::{MuscleStep, MuscleTask, PositionOf, Tracking, TrackingMetrics, TrackingSummary};

/// Desired trajectory at one instant, with analytic derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RefSample {
    /// `x_d` (m).
    pub position_m: f64,
    /// `x_d'` (m/s).
    pub velocity_m_s: f64,
    /// `x_d''` (m/s^2).
    pub acceleration_m_s2: f64,
}

/// What the sensor delivers each period: position only, as on the rig.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measurement {
    /// Measured contraction (m).
    pub position_m: f64,
}

/// Internal states worth plotting; `NaN` where a controller has no such state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Diagnostics {
    /// Proxy position `x_p` (m).
    pub proxy_position_m: f64,
    /// Proxy sliding variable `S_p`, eq. (4) (m/s).
    pub s_p: f64,
    /// Object sliding variable `S_q`, eq. (3) (m/s).
    pub s_q: f64,
    /// Adaptive gain `Gamma_hat`, eq. (10).
    pub gain_hat: f64,
    /// Disturbance estimate `tau_hat`, eq. (37) (m/s^2).
    pub disturbance_hat: f64,
    /// Estimated velocity (m/s).
    pub velocity_m_s: f64,
}

impl Diagnostics {
    /// All states absent.
    pub const NONE: Diagnostics = Diagnostics {
        proxy_position_m: f64::NAN,
        s_p: f64::NAN,
        s_q: f64::NAN,
        gain_hat: f64::NAN,
        disturbance_hat: f64::NAN,
        velocity_m_s: f64::NAN,
    };
}

impl Default for Diagnostics {
    /// All states absent ([`Diagnostics::NONE`]).
    fn default() -> Self {
        Self::NONE
    }
}

/// One period's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlOutput {
    /// Pressure set point (Pa), already clamped to the command limits.
    pub pressure_cmd_pa: f64,
    /// Internal states.
    pub diagnostics: Diagnostics,
}

/// Valve command range the controllers saturate to (and apply anti-windup at).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandLimits {
    /// Lowest command (Pa).
    pub min_pa: f64,
    /// Highest command (Pa).
    pub max_pa: f64,
}

impl Default for CommandLimits {
    /// 0-6 bar: the Festo DMSP-20's operating range.
    fn default() -> Self {
        Self {
            min_pa: 0.0,
            max_pa: 6.0e5,
        }
    }
}

/// Which side a command was clamped on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Saturation {
    /// Within range.
    #[default]
    None,
    /// Clamped to the maximum.
    High,
    /// Clamped to the minimum.
    Low,
}

impl Saturation {
    /// Whether a contribution of sign `push` (positive raises the command) would drive
    /// the command further into this saturation: integrators must then hold.
    pub fn blocks(self, push: f64) -> bool {
        match self {
            Saturation::None => false,
            Saturation::High => push > 0.0,
            Saturation::Low => push < 0.0,
        }
    }
}

impl CommandLimits {
    /// Clamps `u` (NaN becomes the minimum: vent) and reports the side.
    pub fn clamp(&self, u: f64) -> (f64, Saturation) {
        if u.is_nan() || u < self.min_pa {
            (self.min_pa, Saturation::Low)
        } else if u > self.max_pa {
            (self.max_pa, Saturation::High)
        } else {
            (u, Saturation::None)
        }
    }
}

/// A position controller for one muscle. `dt_s` is passed every period; implementations
/// allocate nothing in [`Controller::update`].
pub trait Controller: Send {
    /// Short name as used on the command line (`aprc-ndo`, `psmc`, ...).
    fn name(&self) -> &'static str;
    /// Restarts from rest at `measurement` with the first reference sample (the proxy
    /// starts on the reference, `x_p = x_d`, as Corollaries 1-2 assume).
    fn reset(&mut self, measurement: Measurement, reference: RefSample);
    /// One control period.
    fn update(
        &mut self,
        reference: &RefSample,
        measurement: &Measurement,
        dt_s: f64,
    ) -> ControlOutput;
    /// The actuator got `applied_pa` for the last command (after a safety supervisor's
    /// clamp or rate limit). A controller that remembers its command (for its observer,
    /// its damping mode or its anti-windup) must remember this one instead; when it is
    /// the command itself, nothing changes.
    fn applied(&mut self, applied_pa: f64);
    /// The muscle's pressure as a sensor reads it this period, before [`Controller::update`]
    /// (where the plant has pressure sensors and the run feeds them back). A controller
    /// with a disturbance observer takes it as the observer's input instead of its
    /// nominal valve's estimate: behind a valve that lags, the lag is then not mistaken
    /// for a disturbance and compensated again. The others ignore it.
    fn pressure_sensed(&mut self, pressure_pa: f64) {
        let _ = pressure_pa;
    }
}
