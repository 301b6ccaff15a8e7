//! The trainer's envelope: where a treadmill scenario walks its patient over the body
//! masses, supports, belt speeds and modes a clinic sets (issue 47). Each cell is the
//! scenario with those four changed, and ends one of three ways: refused before it runs
//! (with the reason `simulate` would give), walked (the walking verdict), or run and failed
//! (the verdict's reasons). `pma-exo envelope` runs the cells and draws the map.
use crate::setup::{apply_mode, leg_config, unfit_reason, Mode};
use anyhow::{bail, Result};
use pma_leg::{LegSim, LoadedScenario};
use std::sync::atomic::{AtomicBool, Ordering};

/// One cell of the map: the patient and the trainer's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// The patient's body mass (kg).
    pub mass_kg: f64,
    /// The harness's share of the body weight (0-1).
    pub support: f64,
    /// The walking speed the clinic sets (m/s): the adult reference's speed; the belt runs
    /// at the scenario's own belt speed scaled by it (where the reference's stance moves
    /// with the belt).
    pub speed_m_s: f64,
    /// How the muscles are driven.
    pub mode: Mode,
}

/// What every cell of a map runs beside its point: the muscles' controller (`None`: the
/// scenario's APRC-NDO) with the scenario's gains for it, and the physics step (`None`: the
/// scenario's substeps).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CellSettings {
    /// The controller of every muscle (position and admittance modes).
    pub controller: Option<pma_control::ControllerKind>,
    /// The gains every cell's controller runs with (`None`: the scenario's for it).
    pub gains: Option<pma_control::ControllerConfig>,
    /// `gains` only below this support (a schedule by support; `None`: at every support).
    pub gains_below_support: Option<f64>,
    /// Physics substeps per control period.
    pub physics_substeps: Option<u32>,
    /// The patients' height (m; `None`: the scenario's).
    pub height_m: Option<f64>,
}

impl CellSettings {
    /// The gains a cell at `support` runs with: `gains` below `gains_below_support` (at
    /// every support without it), else `None` (the scenario's).
    pub fn gains_at(&self, support: f64) -> Option<pma_control::ControllerConfig> {
        self.gains
            .filter(|_| self.gains_below_support.is_none_or(|s| support < s))
    }
}

/// How a cell ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Walked within every criterion of the walking verdict.
    Walked,
    /// Ran and did not walk (a collapse, tracking, the belt's load, a muscle's rating).
    Failed,
    /// Refused before it ran.
    Refused,
    /// The simulation left physical bounds (a diverging step, not the patient): no verdict.
    #[serde(rename = "simulation_failed")]
    Unphysical,
    /// The operator stopped it.
    Interrupted,
}

impl Outcome {
    /// Its name, as the table prints it.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Walked => "walked",
            Outcome::Failed => "failed",
            Outcome::Refused => "refused",
            Outcome::Unphysical => "simulation failed",
            Outcome::Interrupted => "interrupted",
        }
    }
}

/// Why a cell was refused, in a word the map can print.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Refusal {
    /// No adult reference at that speed.
    NoReference,
    /// The servo-driven stride asks more than 5 times the adults' moments.
    BeyondNorms,
    /// The scenario's muscles cannot drive the servo-driven stride within their rating.
    Muscles,
    /// Another setting out of its range.
    Invalid,
}

impl Refusal {
    /// A few words for the map.
    pub fn label(self) -> &'static str {
        match self {
            Refusal::NoReference => "no reference",
            Refusal::BeyondNorms => "> 5x adults",
            Refusal::Muscles => "muscles short",
            Refusal::Invalid => "invalid",
        }
    }
}

/// A cell's result.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Cell {
    /// Body mass (kg).
    pub mass_kg: f64,
    /// Height (m), where the map sets one (`--height-m`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub height_m: Option<f64>,
    /// Whether the cell runs the map's gain file (`--gains`; false where a schedule by
    /// support gives it the scenario's), where the map has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gains_file: Option<bool>,
    /// Whether the cell's patient runs the scenario's `control.gains_below_support` set
    /// (its support below the schedule's), where the cell runs the scenario's APRC-NDO gains
    /// and the scenario has a schedule.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gains_scheduled: Option<bool>,
    /// Support (0-1).
    pub support: f64,
    /// Walking speed (m/s).
    pub speed_m_s: f64,
    /// Mode.
    pub mode: String,
    /// The belt's speed (m/s), if the cell got that far.
    pub belt_m_s: Option<f64>,
    /// How it ended.
    pub outcome: Outcome,
    /// Why it was refused, in a word.
    pub refusal: Option<Refusal>,
    /// Why it did not walk (each criterion missed, the walking verdict's reasons) or was
    /// refused (one line); empty if it walked.
    pub reasons: Vec<String>,
    /// Worst stance-phase RMS error over the feet, hip and knee (deg), if it ran.
    pub stance_rms_deg: Option<[f64; 2]>,
    /// Largest peak force of any muscle over its rating, if it ran.
    pub peak_force_over_rated: Option<f64>,
    /// When the trainer's safety stopped a collapse (s).
    pub collapse_s: Option<f64>,
}

impl Cell {
    fn new(p: &Point, outcome: Outcome) -> Self {
        Self {
            mass_kg: p.mass_kg,
            height_m: None,
            gains_file: None,
            gains_scheduled: None,
            support: p.support,
            speed_m_s: p.speed_m_s,
            mode: p.mode.control_mode().to_string(),
            belt_m_s: None,
            outcome,
            refusal: None,
            reasons: Vec::new(),
            stance_rms_deg: None,
            peak_force_over_rated: None,
            collapse_s: None,
        }
    }

    fn refused(p: &Point, belt_m_s: Option<f64>, refusal: Refusal, reason: String) -> Self {
        Self {
            belt_m_s,
            refusal: Some(refusal),
            reasons: vec![reason],
            ..Self::new(p, Outcome::Refused)
        }
    }

    /// A cell whose servo pass or run ended on `e`: a simulation that left physical
    /// bounds says so apart from a patient who did not walk.
    fn failed(p: &Point, belt_m_s: Option<f64>, e: &anyhow::Error) -> Self {
        let unphysical = matches!(
            e.downcast_ref::<pma_leg::LegError>(),
            Some(pma_leg::LegError::LeftPhysics { .. })
        );
        let outcome = if unphysical {
            Outcome::Unphysical
        } else {
            Outcome::Failed
        };
        Self {
            belt_m_s,
            reasons: vec![crate::error_line(e)],
            ..Self::new(p, outcome)
        }
    }

    /// A few words for the map: the worst stance error if it ran, the refusal if not.
    pub fn label(&self) -> String {
        match (
            self.outcome,
            self.refusal,
            self.collapse_s,
            self.stance_rms_deg,
        ) {
            (Outcome::Refused, Some(r), ..) => r.label().to_owned(),
            (Outcome::Failed, _, Some(t), _) => format!("collapse {t:.1} s"),
            (Outcome::Unphysical, ..) => "left physics".into(),
            (_, _, _, Some([h, k])) => format!("{:.2} deg", h.max(k)),
            (o, ..) => o.as_str().to_owned(),
        }
    }
}

/// Checks a treadmill scenario can be mapped: it has a belt and the adults' reference.
pub fn check_base(loaded: &LoadedScenario, arg: &str) -> Result<()> {
    let sc = &loaded.scenario;
    if sc.treadmill.is_none() {
        bail!("{arg}: has no [treadmill]: the envelope maps a gait trainer's patients (gait_treadmill, gait_treadmill_spastic, ...)");
    }
    if sc.gait.speed_m_per_s.is_none() {
        bail!("{arg}: its gait is not the adults' (gait.data = \"fukuchi2018\" with gait.speed_m_per_s): the envelope maps walking speeds");
    }
    Ok(())
}

/// `base` set to `p`: the patient's mass (and `settings`' height), the support (a start's
/// support raised to it), the belt scaled with the walking speed and the legs, the mode.
fn set_point(
    base: &LoadedScenario,
    p: &Point,
    settings: &CellSettings,
) -> Result<(LoadedScenario, Option<f64>)> {
    let mut loaded = base.clone();
    let sc = &mut loaded.scenario;
    if let Some(n) = settings.physics_substeps {
        sc.physics_substeps = n;
    }
    let reference_speed = sc.gait.speed_m_per_s.unwrap_or(p.speed_m_s);
    let mut belt = None;
    if let Some(t) = sc.treadmill.as_mut() {
        // The belt the scenario gives is for its patient's legs; another height's legs
        // walk the same angles at the same cadence as much faster as they are longer.
        let height = |h: Option<f64>| h.unwrap_or(pma_leg::body::URDF_PATIENT_HEIGHT_M);
        let legs = height(settings.height_m) / height(t.height_m);
        if settings.height_m.is_some() {
            t.height_m = settings.height_m;
        }
        t.body_mass_kg = p.mass_kg;
        t.bws_fraction = p.support;
        t.bws_start_fraction = t.bws_start_fraction.map(|s| s.max(p.support));
        let own = t.speed_m_per_s.unwrap_or(reference_speed);
        let scaled = own * p.speed_m_s / reference_speed * legs;
        t.speed_m_per_s = Some(scaled);
        belt = Some(scaled);
    }
    apply_mode(&mut loaded, Some(p.mode), settings.controller)?;
    Ok((loaded, belt))
}

/// Which refusal a validation error is, by the field it names: the belt's speed (within
/// the flag's 0.01-3 m/s, checked before) is refused for having no adult reference.
fn refusal_of(e: &pma_leg::LegError) -> Refusal {
    match e {
        pma_leg::LegError::Invalid(i) if i.name == "treadmill.speed_m_per_s" => {
            Refusal::NoReference
        }
        _ => Refusal::Invalid,
    }
}

/// Runs cell `p` of `base` with `settings` for `duration_s` (stopped early by `stop`).
pub fn run_cell(
    base: &LoadedScenario,
    p: &Point,
    settings: &CellSettings,
    duration_s: f64,
    stop: &AtomicBool,
) -> Cell {
    Cell {
        height_m: settings.height_m,
        gains_file: settings
            .gains
            .map(|_| settings.gains_at(p.support).is_some()),
        gains_scheduled: scheduled(base, p, settings),
        ..cell_outcome(base, p, settings, duration_s, stop)
    }
}

/// Whether cell `p` runs the scenario's `control.gains_below_support` set: `None` where the
/// scenario has no schedule or the cell runs other gains (a file's, another controller's).
fn scheduled(base: &LoadedScenario, p: &Point, settings: &CellSettings) -> Option<bool> {
    use pma_control::ControllerKind as K;
    let control = &base.scenario.control;
    control.gains_below_support.as_ref()?;
    let runs_scenario_aprc = settings.gains_at(p.support).is_none()
        && matches!(settings.controller, None | Some(K::AprcNdo | K::Aprc))
        && p.mode.control_mode().runs_muscle_controllers();
    runs_scenario_aprc.then(|| control.scheduled_at(Some(p.support)).is_some())
}

/// [`run_cell`] before the cell records the settings it ran with.
fn cell_outcome(
    base: &LoadedScenario,
    p: &Point,
    settings: &CellSettings,
    duration_s: f64,
    stop: &AtomicBool,
) -> Cell {
    if stop.load(Ordering::Relaxed) {
        return Cell::new(p, Outcome::Interrupted);
    }
    let (loaded, belt) = match set_point(base, p, settings) {
        Ok(l) => l,
        Err(e) => return Cell::refused(p, None, Refusal::Invalid, format!("{e:#}")),
    };
    if let Err(e) = loaded.scenario.validate() {
        return Cell::refused(p, belt, refusal_of(&e), e.to_string());
    }
    match unfit_reason(&loaded) {
        Ok(None) => {}
        Ok(Some((beyond_norms, why))) => {
            let r = if beyond_norms {
                Refusal::BeyondNorms
            } else {
                Refusal::Muscles
            };
            return Cell::refused(p, belt, r, why);
        }
        Err(e) => return Cell::failed(p, belt, &e),
    }
    match walk(
        &loaded,
        settings.gains_at(p.support),
        settings,
        duration_s,
        stop,
    ) {
        Ok(Some(cell)) => Cell {
            belt_m_s: belt,
            ..cell.at(p)
        },
        Ok(None) => Cell::new(p, Outcome::Interrupted),
        Err(e) => Cell::failed(p, belt, &e),
    }
}

/// What a run gave, before it is placed on the map.
struct Ran {
    walked: bool,
    reasons: Vec<String>,
    stance_rms_deg: [f64; 2],
    peak_force_over_rated: f64,
    collapse_s: Option<f64>,
}

impl Ran {
    fn at(self, p: &Point) -> Cell {
        let outcome = if self.walked {
            Outcome::Walked
        } else {
            Outcome::Failed
        };
        Cell {
            reasons: self.reasons,
            stance_rms_deg: Some(self.stance_rms_deg),
            peak_force_over_rated: Some(self.peak_force_over_rated),
            collapse_s: self.collapse_s,
            ..Cell::new(p, outcome)
        }
    }
}

/// Runs `loaded` with `gains`, or without them `settings`' controller with the scenario's
/// gains for it; `None` if stopped.
fn walk(
    loaded: &LoadedScenario,
    gains: Option<pma_control::ControllerConfig>,
    settings: &CellSettings,
    duration_s: f64,
    stop: &AtomicBool,
) -> Result<Option<Ran>> {
    let config = match gains {
        Some(g) => g,
        None => leg_config(settings.controller, None, loaded)?,
    };
    let mut sim = LegSim::with_controller(loaded, &config)?;
    let run = sim.settings(duration_s)?.with_stop_flag(stop);
    let (report, fault) = sim.run_until_fault(&run, &mut ())?;
    if report.interrupted {
        return Ok(None);
    }
    if let Some(f) = fault.as_ref().filter(|f| f.name != "collapse") {
        bail!("the supervisor stopped the run: {}", f.message);
    }
    let Some(verdict) = report.walking.as_ref() else {
        bail!("the run has no walking verdict (not on a treadmill)");
    };
    let mut stance = [0.0f64; 2];
    for foot in report.treadmill.iter().flat_map(|t| t.feet.values()) {
        for (j, joint) in ["hip", "knee"].iter().enumerate() {
            // A foot with no stance to measure is the worst error there is.
            let rms = foot
                .tracking
                .get(*joint)
                .map_or(f64::INFINITY, |p| p.stance_rms_deg);
            stance[j] = if rms.is_nan() {
                f64::INFINITY
            } else {
                stance[j].max(rms)
            };
        }
    }
    let peak = report
        .safety
        .muscles
        .values()
        .map(|m| m.peak_over_rated)
        .fold(0.0, f64::max);
    Ok(Some(Ran {
        walked: verdict.walking,
        reasons: verdict.reasons.clone(),
        stance_rms_deg: stance,
        peak_force_over_rated: peak,
        collapse_s: verdict.collapse.as_ref().map(|c| c.t_s),
    }))
}

/// Every cell of the grid, mode-major, then speed, support and mass.
pub fn points(masses: &[f64], supports: &[f64], speeds: &[f64], modes: &[Mode]) -> Vec<Point> {
    let mut out = Vec::new();
    for &mode in modes {
        for &speed_m_s in speeds {
            for &support in supports {
                for &mass_kg in masses {
                    out.push(Point {
                        mass_kg,
                        support,
                        speed_m_s,
                        mode,
                    });
                }
            }
        }
    }
    out
}

/// The lowest support at which the patient of `mass_kg` walked in `mode` at `speed_m_s`,
/// and walked at every higher support tried too (`None`: at none of them).
pub fn lowest_support(cells: &[Cell], mode: &str, speed_m_s: f64, mass_kg: f64) -> Option<f64> {
    let mut here: Vec<&Cell> = cells
        .iter()
        .filter(|c| c.mode == mode && c.speed_m_s == speed_m_s && c.mass_kg == mass_kg)
        .collect();
    here.sort_by(|a, b| b.support.total_cmp(&a.support));
    // From the highest support down, as far as every cell walked.
    here.iter()
        .take_while(|c| c.outcome == Outcome::Walked)
        .last()
        .map(|c| c.support)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run that leaves physical bounds is the simulation's failure, not the patient's: the
    /// map keeps it apart (the 50 kg cells were, until the foot's inertia was a body's).
    #[test]
    fn a_diverging_run_is_the_simulations_failure_not_the_patients() {
        let p = Point {
            mass_kg: 50.0,
            support: 0.5,
            speed_m_s: 0.5,
            mode: Mode::Position,
        };
        let diverged = anyhow::Error::new(pma_leg::LegError::LeftPhysics {
            t_s: 0.016,
            what: "the servo-driven knee: it turns at -52.8 rad/s (bound 50 rad/s)".into(),
        });
        let c = Cell::failed(&p, Some(0.4874), &diverged);
        assert_eq!(c.outcome, Outcome::Unphysical);
        assert!(
            c.reasons[0].contains("left physical bounds"),
            "{:?}",
            c.reasons
        );
        let other = anyhow::anyhow!("the patient did not walk");
        assert_eq!(Cell::failed(&p, None, &other).outcome, Outcome::Failed);
    }
}
