use pma_control::AprcGains;
use serde::Deserialize;

/// Controllers: one APRC-NDO per muscle and the co-contraction regulator per joint.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlSettings {
    /// APRC-NDO gains of every muscle (fields left out keep the paper's values).
    #[serde(default)]
    pub gains: AprcGains,
    /// Fraction of the joint inertia reflected through the pulley (`I / r^2`) that each
    /// muscle's nominal model assumes as its mass. The control law turns every m/s^2 of
    /// acceleration error (observer lag, model error) into `m / f1` pascals: with the full
    /// reflected inertia (14 700 kg at the hip) 0.01 m/s^2 is 20 kPa and the valves end up
    /// switching between 0 and 6 bar. A fraction leaves the remaining inertia to the
    /// disturbance observer, the usual nominal-inertia trade-off of DOB control.
    pub nominal_inertia_fraction: f64,
    /// Target common-mode pressure `(p_flexor + p_extensor) / 2` of each joint (Pa).
    pub cocontraction_pa: f64,
    /// Co-contraction regulator: length-reference interference per pascal of common-mode
    /// error (m/Pa).
    pub cocontraction_gain_m_per_pa: f64,
    /// Largest interference (m).
    pub cocontraction_max_m: f64,
    /// Time constant of the common-mode pressure filter (s).
    pub cocontraction_filter_s: f64,
    /// Valve lag the controllers compensate (s), `NominalModel::valve_time_constant_s`;
    /// 0 (the default, the paper) takes each pressure to equal its command.
    #[serde(default)]
    pub nominal_valve_time_constant_s: f64,
    /// Each muscle's pressure sensor feeds its controller's disturbance observer
    /// (`Controller::pressure_sensed`) instead of the observer's own estimate of what the
    /// last command made of the pressure: behind a valve that lags, the lag is then not
    /// taken for a disturbance and compensated a second time. Default off (the paper's
    /// controllers see position only).
    #[serde(default)]
    pub pressure_feedback: bool,
    /// The supervisor's rate limit on every muscle's pressure command (Pa/s). The default,
    /// 6 bar per 1 ms period, binds on nothing the valve's range allows: the shipped
    /// scenarios' controllers step a knee muscle by up to 4.6 bar in one period (`docs/
    /// patient.md`), and the rig's 2 bar per period would change their figures. Set a
    /// lower one to see what a slower valve path does.
    #[serde(default = "default_rate_max")]
    pub pressure_rate_max_pa_per_s: f64,
    /// The share of each muscle's rating its commands may ask ([`crate::control::ForceLimit`]):
    /// every period each command is lowered to the pressure at which the muscle's datasheet
    /// model, at the measured contraction and its rate, pulls this share. In (0, 1]; none
    /// by default (the treadmill scenarios set 0.9).
    #[serde(default)]
    pub force_max_of_rating: Option<f64>,
    /// Which shipped gains the other controllers take (`--controller NAME` without
    /// `--gains`, `compare-leg`): `in-air` (default) or `treadmill`.
    #[serde(default)]
    pub gain_set: crate::control::GainSet,
    /// How the joints are controlled: `position` (default, each muscle's controller
    /// tracking its length) or `impedance` (a spring and damper about the reference by
    /// co-contraction, `[control.impedance]`); `--mode` overrides it.
    #[serde(default)]
    pub mode: crate::control::ControlMode,
    /// Impedance mode's set points.
    #[serde(default)]
    pub impedance: crate::control::ImpedanceSettings,
    /// Path mode's tunnel and support.
    #[serde(default)]
    pub path: crate::control::PathSettings,
    /// What the pressure-set modes carry: `leg` (default, a passive patient) or `device`
    /// (the frames only; an active patient carries their limb).
    #[serde(default)]
    pub compensation: crate::control::Compensation,
}

fn default_rate_max() -> f64 {
    6.0e8
}
