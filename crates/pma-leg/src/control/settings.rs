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
    /// A second APRC-NDO set for patients the harness carries less of (issue 47): where the
    /// treadmill's `bws_fraction` is below `support_fraction`, every muscle's APRC-NDO (and
    /// APRC) runs these gains instead of `gains` (a schedule by support; docs/envelope.md,
    /// "Gains that follow the patient"). Needs a `[treadmill]`; none by default.
    #[serde(default)]
    pub gains_below_support: Option<GainsBelowSupport>,
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

/// `control.gains_below_support`: the APRC-NDO gains a patient on less support runs.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsBelowSupport {
    /// The support (share of the body weight, in [0, 1]) below which `gains` run; 0 switches
    /// the schedule off.
    pub support_fraction: f64,
    /// APRC-NDO gains (fields left out keep the paper's values).
    pub gains: AprcGains,
}

impl ControlSettings {
    /// `gains_below_support` where it applies to a patient on `support` (the harness's
    /// share of their weight; `None` off a treadmill, where nothing is scheduled).
    pub fn scheduled_at(&self, support: Option<f64>) -> Option<&GainsBelowSupport> {
        let support = support?;
        self.gains_below_support
            .as_ref()
            .filter(|s| support < s.support_fraction)
    }
}

fn default_rate_max() -> f64 {
    6.0e8
}

#[cfg(test)]
mod tests {
    use crate::LoadedScenario;

    use pma_control::ControllerConfig;

    fn trainer(name: &str) -> LoadedScenario {
        crate::Scenario::embedded(name).expect("an embedded scenario")
    }

    #[test]
    fn the_shipped_trainers_schedule_is_the_patients_gain_file() {
        let file = ControllerConfig::from_toml_str(include_str!(
            "../../models/gains/treadmill-patients/aprc-ndo.toml"
        ))
        .unwrap();
        for name in [
            "gait_treadmill",
            "gait_treadmill_spastic",
            "gait_treadmill_unsupported",
        ] {
            let control = trainer(name).scenario.control;
            let s = control.gains_below_support.unwrap();
            assert_eq!(ControllerConfig::AprcNdo(s.gains), file, "{name}");
            assert_eq!(s.support_fraction, 0.5, "{name}");
            // `--gains crates/pma-leg/models/gains/treadmill/aprc-ndo.toml` runs the
            // scenario's own set at every support (docs/envelope.md compares the two).
            let own = crate::control::GainSet::Treadmill
                .gains(pma_control::ControllerKind::AprcNdo)
                .unwrap();
            assert_eq!(ControllerConfig::AprcNdo(control.gains), own, "{name}");
        }
    }

    #[test]
    fn a_patient_below_the_schedules_support_runs_its_gains_and_one_from_it_the_scenarios() {
        let mut l = trainer("gait_treadmill");
        let own = l.scenario.control.gains;
        let below = l.scenario.control.gains_below_support.unwrap().gains;
        assert_ne!(own, below);
        for (support, expected) in [
            (0.0, below),
            (0.3, below),
            (0.4999, below),
            (0.5, own),
            (0.9, own),
        ] {
            l.scenario.treadmill.as_mut().unwrap().bws_fraction = support;
            assert_eq!(l.scenario.aprc_gains(), expected, "at {support}");
            let scheduled = l.scenario.control.scheduled_at(l.scenario.support());
            assert_eq!(scheduled.is_some(), support < 0.5, "at {support}");
            let base = crate::scenario::base_config(&l, pma_control::ControllerKind::AprcNdo);
            assert_eq!(base, ControllerConfig::AprcNdo(expected), "at {support}");
        }
        // A fraction of 0 switches the schedule off.
        l.scenario.treadmill.as_mut().unwrap().bws_fraction = 0.0;
        l.scenario
            .control
            .gains_below_support
            .as_mut()
            .unwrap()
            .support_fraction = 0.0;
        assert_eq!(l.scenario.aprc_gains(), own);
        // Off a treadmill no harness carries anything to schedule by.
        assert_eq!(l.scenario.control.scheduled_at(None), None);
    }

    #[test]
    fn a_schedule_off_a_treadmill_is_refused_naming_the_field() {
        let text = format!(
            "{}\n[control.gains_below_support]\nsupport_fraction = 0.5\n[control.gains_below_support.gains]\n",
            include_str!("../../models/scenarios/gait_training.toml")
        );
        let e = crate::Scenario::from_toml_str(&text, "s.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("control.gains_below_support.support_fraction")
                && e.contains("needs a [treadmill]"),
            "{e}"
        );
    }
}
