//! Gains for the leg, found by the same firefly search as the bench's baselines
//! (`crate::tune`): a controller's search space, one gain set shared by the four muscles.
use crate::tune::{firefly, FireflyOptions};
use pma_control::{ControllerConfig, ControllerKind};
use pma_leg::gains::base_config;
use pma_leg::{LegSim, LoadedScenario};

/// Weight of command activity in the objective (deg per bar/s): a chattering valve
/// (hundreds of bar/s) must not buy tracking accuracy.
pub const VARIATION_WEIGHT_DEG_PER_BAR_S: f64 = 0.01;

/// The objective of a run that failed or went non-finite.
pub const FAILED_RUN: f64 = 1000.0;

/// The objective of a run that pulled a muscle past its rating, before the excess: above
/// any tracking figure, below a failed run, so the search climbs back within the rating.
pub const OVER_RATING: f64 = 100.0;

/// Objective of a run of `config` on every muscle: hip RMS + knee RMS (deg, after the
/// first stride; the legs' mean on a two-leg trainer) plus [`VARIATION_WEIGHT_DEG_PER_BAR_S`]
/// times the command variation. Gains that pull any muscle past its rated force track
/// nothing a user may run: such a run scores [`OVER_RATING`] plus 100 times the largest
/// excess (peak force / rating - 1), and a failed or non-finite run [`FAILED_RUN`].
pub fn objective(loaded: &LoadedScenario, config: &ControllerConfig, duration_s: f64) -> f64 {
    let run = || -> Option<f64> {
        let mut sim = LegSim::with_controller(loaded, config).ok()?;
        let r = sim.run(duration_s, &mut ()).ok()?;
        let worst = r
            .safety
            .muscles
            .values()
            .map(|m| m.peak_over_rated)
            .fold(0.0, f64::max);
        // Every leg's mean for each joint (one leg: its own).
        let v = if worst > 1.0 {
            OVER_RATING + 100.0 * (worst - 1.0)
        } else {
            r.joint_rms_deg("hip")
                + r.joint_rms_deg("knee")
                + VARIATION_WEIGHT_DEG_PER_BAR_S * r.command_variation_bar_per_s
        };
        (r.finite && v.is_finite()).then_some(v)
    };
    run().unwrap_or(FAILED_RUN)
}

/// A tuning's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct LegTuning {
    /// The best gains found.
    pub config: ControllerConfig,
    /// Their objective.
    pub objective: f64,
    /// Runs made.
    pub evaluations: usize,
}

/// Tunes `kind`'s gains, shared by the four muscles, on the scenario; `None` if `kind`
/// has no search space.
pub fn tune(
    loaded: &LoadedScenario,
    kind: ControllerKind,
    opts: &FireflyOptions,
    duration_s: f64,
    stop: &std::sync::atomic::AtomicBool,
) -> Option<LegTuning> {
    let space = kind.search_space();
    if space.is_empty() {
        return None;
    }
    let base = base_config(loaded, kind);
    let at = |u: &[f64]| -> Option<ControllerConfig> {
        let mut c = base;
        for (spec, &x) in space.iter().zip(u) {
            c.set_gain(spec.name, spec.search.map(x)?).ok()?;
        }
        c.validate().ok()?;
        Some(c)
    };
    let (u, best, evaluations) = firefly(space.len(), opts, stop, |u| {
        at(u).map_or(FAILED_RUN, |c| objective(loaded, &c, duration_s))
    });
    Some(LegTuning {
        config: at(&u).unwrap_or(base),
        objective: best,
        evaluations,
    })
}
