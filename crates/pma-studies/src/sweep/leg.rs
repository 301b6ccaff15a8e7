//! The leg's grids (`[[leg]]`): scenarios x controllers x gains x patients (presets or a
//! sampled population) x seeds, each run one line of tracking, spasm and safety figures.
//! A run the leg's supervisor stops (a joint out of its window) is a result, recorded
//! with its fault, not an error of the sweep.
use super::{controller_names, embedded, field_error, names, seeds, Job};
use crate::population::MAX_POPULATION;
use crate::StudyError;
use pma_control::{ControllerConfig, ControllerKind};
use pma_leg::patient::{
    EffortSettings, SpasmDirection, SpasmSettings, SpasticityPreset, SpasticitySettings,
};
use pma_leg::{LegReport, LegSim, LoadedScenario, PatientSettings, Scenario};
use pma_model::GaussianRng;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// One leg grid of a sweep file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LegGrid {
    /// Scenarios: embedded names or scenario files (relative to the sweep file).
    pub scenarios: Vec<String>,
    /// Controller names.
    pub controllers: Vec<String>,
    /// Gain sets: `leg` (the shipped leg gains), `scenario` (the scenario's APRC-NDO
    /// gains), or any set a bench grid takes; a pair that does not apply is skipped.
    pub gains: Vec<String>,
    /// Patients (absent: the scenario's own).
    #[serde(default)]
    pub patients: Patients,
    /// Seeds of the random spasms (hip `seed`, knee `seed + 1`) and of the encoders'
    /// noise; absent: the scenario's own.
    #[serde(default)]
    pub seeds: Vec<u64>,
}

impl LegGrid {
    /// How many runs the grid has at most, counted without expanding it; `None` on
    /// overflow.
    pub(super) fn count(&self) -> Option<usize> {
        let population = self.patients.population.as_ref().map_or(0, |p| p.size);
        let patients = self.patients.presets.len().checked_add(population)?;
        [
            self.scenarios.len(),
            self.controllers.len(),
            self.gains.len(),
            self.seeds.len().max(1),
        ]
        .iter()
        .try_fold(patients, |n, &k| n.checked_mul(k))
    }
}

/// The patients of a leg grid.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Patients {
    /// `scenario` (the scenario's own patient), `passive` (no patient: the limb of the
    /// URDF), or a spasticity preset (`none`, `mild`, `moderate`, `severe`) replacing the
    /// scenario's at hip and knee, the rest of its patient kept.
    #[serde(default)]
    pub presets: Vec<String>,
    /// A sampled population.
    #[serde(default)]
    pub population: Option<PatientPopulation>,
}

impl Default for Patients {
    fn default() -> Self {
        Self {
            presets: vec!["scenario".into()],
            population: None,
        }
    }
}

/// A spasticity preset, in order of severity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Spasticity {
    /// No stretch reflex.
    None,
    /// Mild.
    Mild,
    /// Moderate.
    Moderate,
    /// Severe.
    Severe,
}

impl Spasticity {
    /// Every preset, mildest first.
    pub const ALL: [Spasticity; 4] = [Self::None, Self::Mild, Self::Moderate, Self::Severe];

    /// Its name in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Mild => "mild",
            Self::Moderate => "moderate",
            Self::Severe => "severe",
        }
    }

    fn preset(self) -> SpasticityPreset {
        match self {
            Self::None => SpasticityPreset::None,
            Self::Mild => SpasticityPreset::Mild,
            Self::Moderate => SpasticityPreset::Moderate,
            Self::Severe => SpasticityPreset::Severe,
        }
    }
}

/// A seeded population of patients. Patient `k` depends only on the seed and `k`; each
/// draws, uniformly and independently: a spasticity preset between the two given
/// (inclusive), a random spasm rate, the peak torque of its strongest spasms `A` (its
/// spasms' peaks are drawn in `[A/2, A]`, lasting 0.2-0.8 s, either direction), and an
/// effort fraction (> 0 assists, < 0 resists). Hip and knee share the draws; the
/// scenario's passive joint moments are kept.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PatientPopulation {
    /// Number of patients.
    pub size: usize,
    /// Seed.
    pub seed: u64,
    /// Mildest and most severe spasticity.
    pub spasticity: [Spasticity; 2],
    /// Random spasms per minute, at each joint.
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub spasm_rate_per_min: [f64; 2],
    /// Peak torque of the strongest spasms (N m).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub spasm_amplitude_nm: [f64; 2],
    /// Effort as a fraction of the gait's own joint torque.
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub effort_fraction: [f64; 2],
}

/// One patient of a population.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampledPatient {
    /// Spasticity at hip and knee.
    pub spasticity: Spasticity,
    /// Random spasms per minute at each joint.
    pub spasm_rate_per_min: f64,
    /// Peak torque of the strongest spasms (N m).
    pub spasm_amplitude_nm: f64,
    /// Effort fraction.
    pub effort_fraction: f64,
}

/// `[lo, hi]` inside `[min, max]`.
fn range_ok(name: &'static str, r: [f64; 2], min: f64, max: f64) -> Result<(), StudyError> {
    crate::population::range_ok(
        name,
        r,
        min,
        max,
        format!("must be [lo, hi] with {min} <= lo <= hi <= {max}"),
    )
}

impl PatientPopulation {
    /// Checks the size and the ranges (each within what a scenario's patient accepts).
    pub fn validate(&self) -> Result<(), StudyError> {
        if !(1..=MAX_POPULATION).contains(&self.size) {
            return Err(StudyError::from(pma_model::Invalid::new(
                "population.size",
                self.size as f64,
                "must be 1 to 100000 (split larger studies into several sweeps)",
            )));
        }
        if self.spasticity[0] > self.spasticity[1] {
            return Err(StudyError::from(pma_model::Invalid::new(
                "population.spasticity",
                f64::NAN,
                format!(
                    "must be [mildest, most severe]: `{}` is more severe than `{}`",
                    self.spasticity[0].name(),
                    self.spasticity[1].name()
                ),
            )));
        }
        range_ok(
            "population.spasm_rate_per_min",
            self.spasm_rate_per_min,
            0.0,
            pma_leg::patient::MAX_SPASM_RATE_PER_MIN,
        )?;
        range_ok(
            "population.spasm_amplitude_nm",
            self.spasm_amplitude_nm,
            f64::MIN_POSITIVE,
            pma_leg::patient::MAX_PATIENT_TORQUE_NM,
        )?;
        range_ok(
            "population.effort_fraction",
            self.effort_fraction,
            -1.0,
            1.0,
        )
    }

    /// Patient `k`.
    pub fn patient(&self, k: usize) -> SampledPatient {
        let mut rng = GaussianRng::new(
            self.seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(k as u64),
        );
        let [lo, hi] = self.spasticity.map(|s| s as usize);
        // Uniform over the presets lo..=hi (a draw of exactly hi + 1 is clamped).
        let pick = (rng.between(lo as f64, (hi + 1) as f64).floor() as usize).min(hi);
        let mut draw = |r: [f64; 2]| rng.between(r[0], r[1]);
        SampledPatient {
            spasticity: Spasticity::ALL[pick],
            spasm_rate_per_min: draw(self.spasm_rate_per_min),
            spasm_amplitude_nm: draw(self.spasm_amplitude_nm),
            effort_fraction: draw(self.effort_fraction),
        }
    }
}

/// Where a run's patient comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PatientSource {
    /// The scenario's own.
    Scenario,
    /// None: the limb of the URDF.
    Passive,
    /// The scenario's, with this spasticity at hip and knee.
    Preset(Spasticity),
    /// Patient `index` of a population.
    Population {
        /// The ranges.
        population: PatientPopulation,
        /// Which patient.
        index: usize,
    },
}

impl PatientSource {
    /// Its name in `runs.jsonl` (`scenario`, `severe`, `population-17`).
    pub fn label(&self) -> String {
        match self {
            Self::Scenario => "scenario".into(),
            Self::Passive => "passive".into(),
            Self::Preset(s) => s.name().into(),
            Self::Population { index, .. } => format!("population-{index}"),
        }
    }

    /// Its group in summaries (`population` for every sampled patient).
    pub fn group(&self) -> String {
        match self {
            Self::Population { .. } => "population".into(),
            other => other.label(),
        }
    }

    /// `scenario`'s patient replaced as this source says, with spasm seeds `seed`.
    fn apply(&self, scenario: &mut Scenario, seed: Option<u64>) {
        let patient = &mut scenario.patient;
        match *self {
            Self::Scenario => {}
            Self::Passive => *patient = PatientSettings::default(),
            Self::Preset(s) => {
                let preset = spasticity(s);
                patient.hip.spasticity = Some(preset);
                patient.knee.spasticity = Some(preset);
            }
            Self::Population { population, index } => {
                let p = population.patient(index);
                let own_seed = population
                    .seed
                    .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .wrapping_add(index as u64);
                for (j, joint) in [&mut patient.hip, &mut patient.knee]
                    .into_iter()
                    .enumerate()
                {
                    joint.spasticity = Some(spasticity(p.spasticity));
                    joint.spasms = (p.spasm_rate_per_min > 0.0).then(|| SpasmSettings {
                        rate_per_min: p.spasm_rate_per_min,
                        amplitude_nm: [0.5 * p.spasm_amplitude_nm, p.spasm_amplitude_nm],
                        duration_s: [0.2, 0.8],
                        direction: SpasmDirection::Either,
                        rise_fraction: 0.3,
                        seed: own_seed.wrapping_add(j as u64),
                        events: Vec::new(),
                    });
                    joint.effort = Some(EffortSettings {
                        fraction: p.effort_fraction,
                        delay_s: 0.0,
                    });
                }
            }
        }
        if let Some(seed) = seed {
            for (j, joint) in [&mut patient.hip, &mut patient.knee]
                .into_iter()
                .enumerate()
            {
                if let Some(s) = &mut joint.spasms {
                    s.seed = seed.wrapping_add(j as u64);
                }
            }
            scenario.plant.encoder.seed = seed;
        }
    }
}

fn spasticity(s: Spasticity) -> SpasticitySettings {
    SpasticitySettings {
        preset: Some(s.preset()),
        ..SpasticitySettings::default()
    }
}

/// One leg run of a sweep.
#[derive(Debug, Clone)]
pub struct LegPoint {
    /// Position in the sweep (stable for a given file).
    pub index: usize,
    /// The scenario as the sweep file names it.
    pub scenario_label: String,
    /// The scenario as loaded (shared by the grid's runs; the patient and the seed are
    /// set on a copy when the run starts).
    pub scenario: Arc<LoadedScenario>,
    /// Controller.
    pub controller: ControllerKind,
    /// The gain set's name in the file.
    pub gains: String,
    /// The gains.
    pub config: ControllerConfig,
    /// The patient.
    pub patient: PatientSource,
    /// Spasm and encoder seed, if set by the sweep.
    pub seed: Option<u64>,
}

/// A leg run's line in `runs.jsonl`: its parameters and its figures (nothing that depends
/// on the machine or the thread).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegRunRecord {
    /// Index in the sweep.
    pub run: usize,
    /// Scenario, as the sweep file names it.
    pub scenario: String,
    /// Controller.
    pub controller: String,
    /// Gain set.
    pub gains: String,
    /// Patient (`scenario`, `passive`, `severe`, `population-17`).
    pub patient: String,
    /// Group of the patient (`population` for every sampled one).
    pub patient_group: String,
    /// Spasticity preset at hip and knee (`custom` when the scenario sets gains, `none`
    /// without a reflex).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub spasticity: [String; 2],
    /// Random spasms per minute at hip and knee.
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub spasm_rate_per_min: [f64; 2],
    /// Largest peak torque of the random spasms at hip and knee (N m).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub spasm_amplitude_max_nm: [f64; 2],
    /// Effort fraction at hip and knee (> 0 assists).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub effort_fraction: [f64; 2],
    /// Spasm and encoder seed set by the sweep (`null`: the scenario's own).
    pub seed: Option<u64>,
    /// Simulated seconds (up to the fault, if one stopped the run).
    pub ran_s: f64,
    /// Hip tracking error after the first stride, RMS (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub hip_rms_deg: f64,
    /// Its largest (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub hip_max_deg: f64,
    /// Knee tracking error after the first stride, RMS (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub knee_rms_deg: f64,
    /// Its largest (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub knee_max_deg: f64,
    /// Spasms in the run.
    pub spasms: usize,
    /// Largest peak deviation from the reference during a spasm (deg; `null` without
    /// spasms).
    pub spasm_max_deviation_deg: Option<f64>,
    /// Spasms after which the joint was not back within 1 deg within 3 s (overlapped ones
    /// not counted).
    pub spasms_unrecovered: usize,
    /// Mean |du/dt| of the commands (bar/s).
    #[serde(deserialize_with = "nan_if_null")]
    pub command_variation_bar_per_s: f64,
    /// Largest muscle force over its rating.
    #[serde(deserialize_with = "nan_if_null")]
    pub peak_force_over_rated: f64,
    /// Valve saturation, summed over the muscles (s).
    #[serde(deserialize_with = "nan_if_null")]
    pub valve_saturated_s: f64,
    /// Time beyond the URDF joint limits, summed over the joints (s).
    #[serde(deserialize_with = "nan_if_null")]
    pub time_outside_limits_s: f64,
    /// Every figure finite.
    pub finite: bool,
    /// On a treadmill, whether the patient walked (`pma_leg::verdict`); `null` in the air.
    #[serde(default)]
    pub walking: Option<bool>,
    /// On a two-leg trainer, each leg's hip and knee RMS error (deg) by side; empty for
    /// one leg (its figures are the ones above).
    #[serde(default)]
    pub legs: std::collections::BTreeMap<String, LegFigures>,
    /// The supervisor's fault that stopped the run (`position-out`, ...), if any.
    pub fault: Option<String>,
    /// When it stopped the run (s).
    pub fault_t_s: Option<f64>,
}

/// One leg's figures of a two-leg run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegFigures {
    /// Hip tracking error after the first stride, RMS (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub hip_rms_deg: f64,
    /// Knee tracking error after the first stride, RMS (deg).
    #[serde(deserialize_with = "nan_if_null")]
    pub knee_rms_deg: f64,
}

/// A figure a run could not give is written `null` (JSON has no NaN) and read back as
/// NaN, so that a sweep reads its own lines.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Option::<f64>::deserialize(d).map(|v| v.unwrap_or(f64::NAN))
}

/// The spasticity preset of a joint's settings, by name.
fn spasticity_name(s: Option<&SpasticitySettings>) -> String {
    let Some(s) = s else {
        return "none".into();
    };
    let overridden = s.extensor_gain_nm_s_per_rad.is_some()
        || s.flexor_gain_nm_s_per_rad.is_some()
        || s.threshold_rad_s.is_some()
        || s.delay_s.is_some();
    match s.preset {
        _ if overridden => "custom".into(),
        None | Some(SpasticityPreset::None) => "none".into(),
        Some(SpasticityPreset::Mild) => "mild".into(),
        Some(SpasticityPreset::Moderate) => "moderate".into(),
        Some(SpasticityPreset::Severe) => "severe".into(),
    }
}

impl LegPoint {
    /// The scenario as the sweep file names it.
    pub fn scenario_name(&self) -> &str {
        &self.scenario_label
    }

    /// The scenario's control period (s).
    pub fn period_s(&self) -> f64 {
        self.scenario.scenario.period_s
    }

    /// The scenario with this run's patient and seed.
    pub fn scenario(&self) -> Scenario {
        let mut sc = self.scenario.scenario.clone();
        self.patient.apply(&mut sc, self.seed);
        sc
    }

    /// Runs it for `duration_s` and returns its line.
    pub fn run(&self, duration_s: f64) -> Result<LegRunRecord, StudyError> {
        let loaded = LoadedScenario {
            scenario: self.scenario(),
            ..(*self.scenario).clone()
        };
        let mut sim = LegSim::with_controller(&loaded, &self.config)?;
        let settings = sim.settings(duration_s)?;
        let (report, fault) = sim.run_until_fault(&settings, &mut ())?;
        Ok(self.record(&loaded.scenario, &report, fault))
    }

    fn record(
        &self,
        scenario: &Scenario,
        report: &LegReport,
        fault: Option<pma_leg::LegFault>,
    ) -> LegRunRecord {
        let row = crate::compare::CompareRow::of(report, self.controller.as_str());
        // Every leg's joint of that name: the legs' mean RMS, the largest error.
        let joint = |j: &str| {
            let max = report
                .joints
                .iter()
                .filter(|(k, _)| *k == j || k.ends_with(&format!("/{j}")))
                .map(|(_, s)| s.max_deg)
                .fold(f64::NAN, f64::max);
            (report.joint_rms_deg(j), max)
        };
        let legs = report
            .joints
            .keys()
            .filter_map(|k| k.split_once('/').map(|(side, _)| side.to_owned()))
            .map(|side| {
                let rms = |j: &str| {
                    report
                        .joints
                        .get(&format!("{side}/{j}"))
                        .map_or(f64::NAN, |s| s.rms_deg)
                };
                let figures = LegFigures {
                    hip_rms_deg: rms("hip"),
                    knee_rms_deg: rms("knee"),
                };
                (side, figures)
            })
            .collect();
        let (hip_rms_deg, hip_max_deg) = joint("hip");
        let (knee_rms_deg, knee_max_deg) = joint("knee");
        let joints = [&scenario.patient.hip, &scenario.patient.knee];
        LegRunRecord {
            run: self.index,
            scenario: self.scenario_label.clone(),
            controller: self.controller.as_str().to_owned(),
            gains: self.gains.clone(),
            patient: self.patient.label(),
            patient_group: self.patient.group(),
            spasticity: joints.map(|j| spasticity_name(j.spasticity.as_ref())),
            spasm_rate_per_min: joints.map(|j| j.spasms.as_ref().map_or(0.0, |s| s.rate_per_min)),
            spasm_amplitude_max_nm: joints.map(|j| {
                j.spasms
                    .as_ref()
                    .filter(|s| s.rate_per_min > 0.0)
                    .map_or(0.0, |s| s.amplitude_nm[1])
            }),
            effort_fraction: joints.map(|j| j.effort.map_or(0.0, |e| e.fraction)),
            seed: self.seed,
            ran_s: report.duration_s,
            hip_rms_deg,
            hip_max_deg,
            knee_rms_deg,
            knee_max_deg,
            spasms: row.spasms,
            spasm_max_deviation_deg: row.spasm_max_deviation_deg,
            spasms_unrecovered: row.spasms_unrecovered,
            command_variation_bar_per_s: row.command_variation_bar_per_s,
            peak_force_over_rated: row.peak_force_over_rated,
            valve_saturated_s: row.valve_saturated_s,
            time_outside_limits_s: row.time_outside_limits_s,
            finite: row.finite,
            walking: report.walking.as_ref().map(|v| v.walking),
            legs,
            fault: fault.as_ref().map(|f| f.name.to_owned()),
            fault_t_s: fault.map(|f| f.t_s),
        }
    }
}

/// The patients of a grid.
fn patients(grid: &LegGrid, file: &str, g: usize) -> Result<Vec<PatientSource>, StudyError> {
    let field = format!("leg[{g}].patients.presets");
    let mut out = Vec::new();
    for name in &grid.patients.presets {
        out.push(match name.as_str() {
            "scenario" => PatientSource::Scenario,
            "passive" => PatientSource::Passive,
            other => match Spasticity::ALL.iter().find(|s| s.name() == other) {
                Some(s) => PatientSource::Preset(*s),
                None => {
                    return Err(field_error(
                        file,
                        &field,
                        format!(
                            "unknown patient `{other}` (expected scenario, passive, none, mild, moderate or severe)"
                        ),
                    ))
                }
            },
        });
    }
    if let Some(p) = grid.patients.population {
        out.extend((0..p.size).map(|index| PatientSource::Population {
            population: p,
            index,
        }));
    }
    if out.is_empty() {
        return Err(field_error(
            file,
            &format!("leg[{g}].patients"),
            "no patient (give presets or a population)".into(),
        ));
    }
    Ok(out)
}

/// A scenario of a grid: an embedded name, or a file relative to the sweep file's `dir`.
fn load_scenario(name: &str, dir: &Path) -> Result<LoadedScenario, StudyError> {
    let path = if name.ends_with(".toml") {
        dir.join(name).display().to_string()
    } else {
        name.to_owned()
    };
    Ok(Scenario::load(&path)?)
}

/// Appends the runs of leg grid `g` to `jobs`; `duration_s` is the sweep's.
pub(super) fn expand(
    grid: &LegGrid,
    duration_s: f64,
    file: &str,
    dir: &Path,
    g: usize,
    jobs: &mut Vec<Job>,
) -> Result<(), StudyError> {
    let at = |f: &str| format!("leg[{g}].{f}");
    let controllers = names(
        &grid.controllers,
        &controller_names(),
        file,
        &at("controllers"),
    )?;
    for (field, empty) in [
        ("scenarios", grid.scenarios.is_empty()),
        ("controllers", controllers.is_empty()),
        ("gains", grid.gains.is_empty()),
    ] {
        if empty {
            return Err(field_error(
                file,
                &at(field),
                "empty: nothing to run".into(),
            ));
        }
    }
    let patients = patients(grid, file, g)?;
    let seeds = seeds(&grid.seeds);
    for name in &grid.scenarios {
        let loaded = load_scenario(name, dir)
            .map_err(|e| field_error(file, &at("scenarios"), e.to_string()))?;
        loaded
            .scenario
            .check_run_duration(duration_s)
            .map_err(|e| field_error(file, "duration_s", e.to_string()))?;
        // The gains first: `scenario` gains are the scenario's.
        let mut configs = Vec::new();
        for &controller in &controllers {
            for gains in &grid.gains {
                if let Some(config) = embedded::gains_for(controller, gains, dir, Some(&loaded))
                    .map_err(|m| field_error(file, &at("gains"), m))?
                {
                    configs.push((controller, gains, config));
                }
            }
        }
        let loaded = Arc::new(loaded);
        for patient in &patients {
            for &seed in &seeds {
                // Each patient checked now, so that a sweep never fails halfway.
                let mut sc = loaded.scenario.clone();
                patient.apply(&mut sc, seed);
                sc.validate().map_err(|e| {
                    field_error(
                        file,
                        &at("patients"),
                        format!("patient {} on {name}: {e}", patient.label()),
                    )
                })?;
                for (controller, gains, config) in &configs {
                    jobs.push(Job::Leg(LegPoint {
                        index: jobs.len(),
                        scenario_label: name.clone(),
                        scenario: Arc::clone(&loaded),
                        controller: *controller,
                        gains: (*gains).clone(),
                        config: *config,
                        patient: *patient,
                        seed,
                    }));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pop() -> PatientPopulation {
        PatientPopulation {
            size: 200,
            seed: 3,
            spasticity: [Spasticity::Mild, Spasticity::Severe],
            spasm_rate_per_min: [0.0, 6.0],
            spasm_amplitude_nm: [5.0, 30.0],
            effort_fraction: [-0.3, 0.1],
        }
    }

    #[test]
    fn a_patient_depends_on_its_index_only_and_stays_in_range() {
        let p = pop();
        p.validate().unwrap();
        assert_eq!(p.patient(17), p.patient(17));
        assert_ne!(p.patient(17), p.patient(18));
        let mut seen = std::collections::BTreeSet::new();
        for k in 0..p.size {
            let s = p.patient(k);
            seen.insert(s.spasticity);
            assert!((0.0..=6.0).contains(&s.spasm_rate_per_min));
            assert!((5.0..=30.0).contains(&s.spasm_amplitude_nm));
            assert!((-0.3..=0.1).contains(&s.effort_fraction));
        }
        // Every preset of the range, and none outside it.
        assert_eq!(
            seen.into_iter().collect::<Vec<_>>(),
            [Spasticity::Mild, Spasticity::Moderate, Spasticity::Severe]
        );
    }

    #[test]
    fn a_population_out_of_the_patients_ranges_is_refused() {
        let reversed = PatientPopulation {
            spasticity: [Spasticity::Severe, Spasticity::None],
            ..pop()
        };
        assert!(reversed
            .validate()
            .unwrap_err()
            .to_string()
            .contains("severe"));
        let fast = PatientPopulation {
            spasm_rate_per_min: [0.0, 120.0],
            ..pop()
        };
        assert!(fast.validate().unwrap_err().to_string().contains("rate"));
        let strong = PatientPopulation {
            effort_fraction: [-2.0, 0.0],
            ..pop()
        };
        assert!(strong
            .validate()
            .unwrap_err()
            .to_string()
            .contains("effort"));
    }

    #[test]
    fn a_sampled_patient_sets_both_joints_and_the_seed_moves_its_spasms() {
        let mut sc = Scenario::load("gait_training").unwrap().scenario;
        let source = PatientSource::Population {
            population: pop(),
            index: 4,
        };
        let drawn = pop().patient(4);
        source.apply(&mut sc, Some(9));
        sc.validate().unwrap();
        for j in [&sc.patient.hip, &sc.patient.knee] {
            assert_eq!(j.effort.map(|e| e.fraction), Some(drawn.effort_fraction));
            assert_eq!(
                j.spasticity.and_then(|s| s.preset),
                Some(drawn.spasticity.preset())
            );
        }
        if let (Some(h), Some(k)) = (&sc.patient.hip.spasms, &sc.patient.knee.spasms) {
            assert_eq!((h.seed, k.seed), (9, 10));
        }
        assert_eq!(sc.plant.encoder.seed, 9);
    }
}
