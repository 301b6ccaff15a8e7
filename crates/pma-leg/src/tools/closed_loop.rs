//! The closed-loop check of a sizing: the scenario run with the recommended muscles under
//! its own controller, valves and patient, and each joint's peak force against the servo
//! figure the sizing kept its margin on. A servo drives the joints exactly along the
//! reference; a controller behind a real valve adds its own activity (co-contraction,
//! corrections, chatter), which the margin is there to absorb. APRC-NDO behind the trainer's
//! valves drives them to their cap whatever the muscle (docs/treadmill.md), so a larger
//! muscle does not shrink its share: a scenario that holds its muscles with a force limit
//! (`[control] force_max_of_rating`, the shipped treadmill scenarios) is checked with that
//! limit lowered to the stated margin (`1 - margin`), and the question becomes whether the
//! patient still walks under it.
use crate::base::LegError;
use crate::scenario::LoadedScenario;
use crate::sim::LegSim;
use crate::tools::{muscle_geometry, Sizing};
use serde::Serialize;
use std::sync::atomic::AtomicBool;

/// How far a closed-loop peak may go above the servo figure's allowance before the
/// sizing is said not to hold: a tenth of the rating (the closed loop stays "within its
/// stated margin to 10 % of the rating").
pub const CLOSED_LOOP_TOLERANCE: f64 = 0.10;

/// Shortest closed-loop check (s): two strides of the slowest reference and its start-up.
pub const CLOSED_LOOP_MIN_S: f64 = 4.0;

/// Longest closed-loop check (s).
pub const CLOSED_LOOP_MAX_S: f64 = 600.0;

/// The closed-loop check's default length (s): the walking verdict's run (a treadmill
/// scenario walks 60 s to be said to walk). A marginal loop can hold a shorter check and
/// collapse later: the unsupported trainer's second design walked 20 s and collapsed at
/// 32.11 s (docs/treadmill.md).
pub const CLOSED_LOOP_DEFAULT_S: f64 = 60.0;

/// One joint in the closed loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosedLoopJoint {
    /// `hip` or `knee`.
    pub joint: String,
    /// The recommended pair's peak force over its rating with the servo (the sizing's).
    pub servo_peak_over_rated: f64,
    /// The largest peak force over rating of the joint's muscles, every leg, in the
    /// closed loop.
    pub peak_over_rated: f64,
    /// The most the closed loop may reach: `1 - stated_margin + CLOSED_LOOP_TOLERANCE`.
    pub allowed_over_rated: f64,
}

/// A sizing's recommendation run in closed loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClosedLoop {
    /// Simulated seconds.
    pub duration_s: f64,
    /// The force margin asked for (`size --force-margin`), which the closed loop is held to.
    pub stated_margin: f64,
    /// The force margin this sizing was made with: the stated one, or one raised after an
    /// earlier check.
    pub force_margin: f64,
    /// The force limit the run held every muscle's command to (`[control]
    /// force_max_of_rating`): `1 - stated_margin` or the scenario's own where lower, when
    /// the scenario sets one (`None` otherwise). A run of the recommendation needs it in its
    /// scenario to stay within the margin.
    pub force_max_of_rating: Option<f64>,
    /// Each joint's peaks.
    pub joints: Vec<ClosedLoopJoint>,
    /// Whether the patient walked (a treadmill run's verdict; `None` in the air).
    pub walking: Option<bool>,
    /// Why not, one line (the verdict's, or the fault that stopped the run).
    pub why_not: Option<String>,
    /// Whether every joint stayed within its allowance and the run ended without a fault
    /// (and, on a treadmill, walked).
    pub holds: bool,
}

impl ClosedLoop {
    /// The largest amount by which a joint's closed-loop peak exceeded its servo figure
    /// (0 when none did): the controller's own share of the rating.
    pub fn controller_share(&self) -> f64 {
        self.joints
            .iter()
            .map(|j| j.peak_over_rated - j.servo_peak_over_rated)
            .fold(0.0, f64::max)
    }
}

/// The force limit a closed-loop check holds the muscles to, where the scenario sets one:
/// the share of the rating the stated margin leaves, or the scenario's own where lower.
fn force_limit_of(stated_margin: f64, loaded: &LoadedScenario) -> Option<f64> {
    let scenario = loaded.scenario.control.force_max_of_rating?;
    Some((1.0 - stated_margin).min(scenario))
}

/// Runs `loaded` for `duration_s` with `sizing`'s recommended muscles and co-contraction
/// (made with `margins.1`) under the scenario's controller, each joint held to the stated
/// margin `margins.0` (a scenario's force limit lowered to `1 - margins.0`); `None` when
/// the sizing recommends nothing. `stop` ends the run
/// early: the check then covers what ran.
pub fn closed_loop(
    loaded: &LoadedScenario,
    sizing: &Sizing,
    (stated_margin, force_margin): (f64, f64),
    duration_s: f64,
    stop: &AtomicBool,
) -> Result<Option<ClosedLoop>, LegError> {
    let (Some(muscles), Some(cocontraction_pa)) =
        (muscle_geometry(sizing), sizing.cocontraction_pa)
    else {
        return Ok(None);
    };
    let mut sized = loaded.clone();
    sized.muscles = muscles;
    sized.muscles_source = "the sizing's recommendation".into();
    sized.scenario.control.cocontraction_pa = cocontraction_pa;
    let force_max_of_rating = force_limit_of(stated_margin, loaded);
    sized.scenario.control.force_max_of_rating = force_max_of_rating;
    let mut sim = LegSim::new(&sized)?;
    let settings = sim.settings(duration_s)?.with_stop_flag(stop);
    let (report, fault) = sim.run_until_fault(&settings, &mut ())?;
    let allowed = 1.0 - stated_margin + CLOSED_LOOP_TOLERANCE;
    let joints: Vec<ClosedLoopJoint> = sizing
        .joints
        .iter()
        .filter_map(|j| {
            let servo = j.recommended?.peak_force_over_rated;
            let peak = report
                .safety
                .muscles
                .iter()
                .filter(|(name, _)| {
                    let own = name.rsplit('/').next().unwrap_or(name);
                    own.starts_with(&format!("{}_", j.joint))
                })
                .map(|(_, m)| m.peak_over_rated)
                .fold(f64::NAN, f64::max);
            Some(ClosedLoopJoint {
                joint: j.joint.clone(),
                servo_peak_over_rated: servo,
                peak_over_rated: peak,
                allowed_over_rated: allowed,
            })
        })
        .collect();
    let walking = report.walking.as_ref().map(|w| w.walking);
    let why_not = match (&fault, &report.walking) {
        (Some(f), _) => Some(format!("{} at {:.2} s: {}", f.name, f.t_s, f.message)),
        (None, Some(w)) if !w.walking => Some(w.line()),
        _ => None,
    };
    let within = joints
        .iter()
        .all(|j| j.peak_over_rated <= j.allowed_over_rated);
    Ok(Some(ClosedLoop {
        duration_s: report.duration_s,
        stated_margin,
        force_margin,
        force_max_of_rating,
        holds: within && why_not.is_none() && report.finite,
        joints,
        walking,
        why_not,
    }))
}
