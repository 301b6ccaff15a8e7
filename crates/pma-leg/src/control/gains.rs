//! Gains tuned for the leg, one file per controller and place: in the air
//! (`crates/pma-leg/models/gains/`, each found by `pma-exo tune-leg gait_training
//! --controller NAME`) and on the two-leg treadmill (`crates/pma-leg/models/gains/treadmill/`,
//! `pma-exo tune-leg gait_treadmill --also gait_treadmill_spastic --controller NAME
//! --duration 17.5`, or the previous gains where they did better over 60 s:
//! docs/treadmill.md), with the same budget.
//! A scenario's `control.gain_set` says which set its controllers take; its own APRC-NDO
//! gains (`control.gains`) stay the APRC-NDO's.
use crate::base::LegError;
use pma_control::{ControllerConfig, ControllerKind};

/// The shipped leg gain files: controller and text.
pub const LEG_GAINS: [(ControllerKind, &str); 5] = [
    (
        ControllerKind::AprcNdo,
        include_str!("../../models/gains/aprc-ndo.toml"),
    ),
    (
        ControllerKind::Psmc,
        include_str!("../../models/gains/psmc.toml"),
    ),
    (
        ControllerKind::NdoSmc,
        include_str!("../../models/gains/ndo-smc.toml"),
    ),
    (
        ControllerKind::Sta,
        include_str!("../../models/gains/sta.toml"),
    ),
    (
        ControllerKind::Pid,
        include_str!("../../models/gains/pid.toml"),
    ),
];

/// The shipped two-leg treadmill gain files: controller and text.
pub const TREADMILL_GAINS: [(ControllerKind, &str); 5] = [
    (
        ControllerKind::AprcNdo,
        include_str!("../../models/gains/treadmill/aprc-ndo.toml"),
    ),
    (
        ControllerKind::Psmc,
        include_str!("../../models/gains/treadmill/psmc.toml"),
    ),
    (
        ControllerKind::NdoSmc,
        include_str!("../../models/gains/treadmill/ndo-smc.toml"),
    ),
    (
        ControllerKind::Sta,
        include_str!("../../models/gains/treadmill/sta.toml"),
    ),
    (
        ControllerKind::Pid,
        include_str!("../../models/gains/treadmill/pid.toml"),
    ),
];

/// The two-leg treadmill's gain files from before issue 46, tuned behind an instantaneous
/// valve (the pressure-set modes' and the ideal valve's figures were found with them).
pub const TREADMILL_IDEAL_GAINS: [(ControllerKind, &str); 5] = [
    (
        ControllerKind::AprcNdo,
        include_str!("../../models/gains/treadmill-ideal/aprc-ndo.toml"),
    ),
    (
        ControllerKind::Psmc,
        include_str!("../../models/gains/treadmill-ideal/psmc.toml"),
    ),
    (
        ControllerKind::NdoSmc,
        include_str!("../../models/gains/treadmill-ideal/ndo-smc.toml"),
    ),
    (
        ControllerKind::Sta,
        include_str!("../../models/gains/treadmill-ideal/sta.toml"),
    ),
    (
        ControllerKind::Pid,
        include_str!("../../models/gains/treadmill-ideal/pid.toml"),
    ),
];

/// Which shipped gains a scenario's controllers take (its own APRC-NDO gains aside).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GainSet {
    /// Tuned on the in-air leg (`gait_training`); `in_air` is read as `in-air`.
    #[default]
    #[serde(alias = "in_air")]
    InAir,
    /// Tuned on the two-leg treadmill (`gait_treadmill`) behind its MPYE-5-1/4 valves.
    Treadmill,
    /// Tuned on the two-leg treadmill behind an instantaneous valve (before issue 46).
    TreadmillIdeal,
}

impl GainSet {
    /// The set's name as scenarios and outputs give it.
    pub fn as_str(self) -> &'static str {
        match self {
            GainSet::InAir => "in-air",
            GainSet::Treadmill => "treadmill",
            GainSet::TreadmillIdeal => "treadmill-ideal",
        }
    }

    fn files(self) -> (&'static [(ControllerKind, &'static str)], &'static str) {
        match self {
            GainSet::InAir => (&LEG_GAINS, "crates/pma-leg/models/gains"),
            GainSet::Treadmill => (&TREADMILL_GAINS, "crates/pma-leg/models/gains/treadmill"),
            GainSet::TreadmillIdeal => (
                &TREADMILL_IDEAL_GAINS,
                "crates/pma-leg/models/gains/treadmill-ideal",
            ),
        }
    }

    /// Where the set's files are, from the repository's root.
    pub fn directory(self) -> &'static str {
        self.files().1
    }

    /// `kind`'s gains of this set; its defaults if none were shipped.
    pub fn gains(self, kind: ControllerKind) -> Result<ControllerConfig, LegError> {
        let (files, dir) = self.files();
        let Some((_, text)) = files.iter().find(|(k, _)| *k == kind) else {
            return Ok(kind.default_config());
        };
        ControllerConfig::from_toml_str(text).map_err(|e| LegError::Parse {
            file: format!("{dir}/{kind}.toml"),
            message: e.to_string(),
        })
    }
}

/// `kind`'s shipped leg gains; its defaults if none were shipped.
pub fn leg_gains(kind: ControllerKind) -> Result<ControllerConfig, LegError> {
    GainSet::InAir.gains(kind)
}
