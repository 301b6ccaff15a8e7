//! Gains tuned for the leg (`crates/pma-leg/models/gains/`), one file per controller, each found by
//! `pma-exo tune-leg gait_training --controller NAME` with the same budget.
use crate::config::LoadedScenario;
use crate::error::LegError;
use pma_control::{ControllerConfig, ControllerKind};

/// The shipped leg gain files: controller and text.
pub const LEG_GAINS: [(ControllerKind, &str); 5] = [
    (
        ControllerKind::AprcNdo,
        include_str!("../models/gains/aprc-ndo.toml"),
    ),
    (
        ControllerKind::Psmc,
        include_str!("../models/gains/psmc.toml"),
    ),
    (
        ControllerKind::NdoSmc,
        include_str!("../models/gains/ndo-smc.toml"),
    ),
    (
        ControllerKind::Sta,
        include_str!("../models/gains/sta.toml"),
    ),
    (
        ControllerKind::Pid,
        include_str!("../models/gains/pid.toml"),
    ),
];

/// `kind`'s shipped leg gains; its defaults if none were shipped.
pub fn leg_gains(kind: ControllerKind) -> Result<ControllerConfig, LegError> {
    let Some((_, text)) = LEG_GAINS.iter().find(|(k, _)| *k == kind) else {
        return Ok(kind.default_config());
    };
    let config = ControllerConfig::from_toml_str(text).map_err(|e| LegError::Parse {
        file: format!("crates/pma-leg/models/gains/{kind}.toml"),
        message: e.to_string(),
    })?;
    Ok(config)
}

/// The configuration a tuning starts from and keeps outside its search space: the
/// scenario's APRC-NDO gains for APRC-NDO and APRC, the controller's defaults otherwise.
pub fn base_config(loaded: &LoadedScenario, kind: ControllerKind) -> ControllerConfig {
    let g = loaded.scenario.control.gains;
    match kind {
        ControllerKind::AprcNdo => ControllerConfig::AprcNdo(g),
        ControllerKind::Aprc => ControllerConfig::Aprc(g),
        other => other.default_config(),
    }
}
