//! Gains for the leg, found by the same firefly search as the bench's baselines
//! (`pma_sim::tune`): APRC-NDO's search space, one gain set shared by the four muscles.
use crate::config::LoadedScenario;
use crate::sim::LegSim;
use pma_control::{AprcGains, ControllerConfig, ControllerKind};
use pma_sim::tune::{config_at, firefly, search_space, FireflyOptions};

/// Weight of command activity in the objective (deg per bar/s): a chattering valve
/// (hundreds of bar/s) must not buy tracking accuracy.
pub const VARIATION_WEIGHT_DEG_PER_BAR_S: f64 = 0.01;

/// The objective of a run that failed or went non-finite.
pub const FAILED_RUN: f64 = 1000.0;

/// Objective of a run: hip RMS + knee RMS (deg, after the first stride) plus
/// [`VARIATION_WEIGHT_DEG_PER_BAR_S`] times the command variation; a failed or
/// non-finite run scores [`FAILED_RUN`].
pub fn objective(loaded: &LoadedScenario, gains: AprcGains, duration_s: f64) -> f64 {
    let mut l = loaded.clone();
    l.scenario.control.gains = gains;
    let run = || -> Option<f64> {
        let mut sim = LegSim::new(&l).ok()?;
        let r = sim.run(duration_s, &mut ()).ok()?;
        let j = |n: &str| r.joints.get(n).map(|s| s.rms_deg);
        let v =
            j("hip")? + j("knee")? + VARIATION_WEIGHT_DEG_PER_BAR_S * r.command_variation_bar_per_s;
        (r.finite && v.is_finite()).then_some(v)
    };
    run().unwrap_or(FAILED_RUN)
}

/// Tunes the scenario's shared APRC-NDO gains; returns them, their objective and the runs.
pub fn tune(
    loaded: &LoadedScenario,
    opts: &FireflyOptions,
    duration_s: f64,
) -> (AprcGains, f64, usize) {
    let kind = ControllerKind::AprcNdo;
    let dims = search_space(kind).map_or(0, |s| s.len());
    let gains_at = |u: &[f64]| match config_at(kind, u) {
        Some(ControllerConfig::AprcNdo(g)) => Some(AprcGains {
            boundary_layer_m_s: loaded.scenario.control.gains.boundary_layer_m_s,
            ..g
        }),
        _ => None,
    };
    let (u, best, evals) = firefly(dims, opts, |u| {
        gains_at(u)
            .filter(|g| ControllerConfig::AprcNdo(*g).validate().is_ok())
            .map_or(FAILED_RUN, |g| objective(loaded, g, duration_s))
    });
    (
        gains_at(&u).unwrap_or(loaded.scenario.control.gains),
        best,
        evals,
    )
}
