//! Gains tuned for the leg (`models/gains/leg/`), one file per controller, each found by
//! `pma-exo tune-leg gait_training --controller NAME` with the same budget.
use crate::error::LegError;
use pma_control::{ControllerConfig, ControllerKind};

/// The shipped leg gain files: controller and text.
pub const LEG_GAINS: [(ControllerKind, &str); 5] = [
    (
        ControllerKind::AprcNdo,
        include_str!("../../../models/gains/leg/aprc-ndo.toml"),
    ),
    (
        ControllerKind::Psmc,
        include_str!("../../../models/gains/leg/psmc.toml"),
    ),
    (
        ControllerKind::NdoSmc,
        include_str!("../../../models/gains/leg/ndo-smc.toml"),
    ),
    (
        ControllerKind::Sta,
        include_str!("../../../models/gains/leg/sta.toml"),
    ),
    (
        ControllerKind::Pid,
        include_str!("../../../models/gains/leg/pid.toml"),
    ),
];

/// `kind`'s shipped leg gains; its defaults if none were shipped.
pub fn leg_gains(kind: ControllerKind) -> Result<ControllerConfig, LegError> {
    let Some((_, text)) = LEG_GAINS.iter().find(|(k, _)| *k == kind) else {
        return Ok(kind.default_config());
    };
    let config = ControllerConfig::from_toml_str(text).map_err(|e| LegError::Parse {
        file: format!("models/gains/leg/{kind}.toml"),
        message: e.to_string(),
    })?;
    Ok(config)
}
