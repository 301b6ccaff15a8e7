use crate::base::LegError;
use crate::scenario::LoadedScenario;
use pma_control::{ControllerConfig, ControllerKind};

/// The gains `kind` runs with on a scenario: the scenario's own for APRC-NDO (and, without
/// its observer, APRC), the scenario's gain set's for the others. One name, one gain set.
pub fn scenario_gains(
    loaded: &LoadedScenario,
    kind: ControllerKind,
) -> Result<ControllerConfig, LegError> {
    match kind {
        ControllerKind::AprcNdo | ControllerKind::Aprc => Ok(base_config(loaded, kind)),
        other => loaded.scenario.control.gain_set.gains(other),
    }
}

/// The configuration a tuning starts from and keeps outside its search space: the
/// scenario's APRC-NDO gains for APRC-NDO and APRC (those its patient's support selects,
/// `Scenario::aprc_gains`), the controller's defaults otherwise.
pub fn base_config(loaded: &LoadedScenario, kind: ControllerKind) -> ControllerConfig {
    let g = loaded.scenario.aprc_gains();
    match kind {
        ControllerKind::AprcNdo => ControllerConfig::AprcNdo(g),
        ControllerKind::Aprc => ControllerConfig::Aprc(g),
        other => other.default_config(),
    }
}
