//! Sweeps: a TOML-described set of grids, run in parallel, each run's parameters and
//! figures one JSON line of `runs.jsonl`; shards for cluster job arrays, resumption after
//! a kill, merging and a summary. A grid runs the bench (controllers x gains x plants or
//! sampled plant populations x references x events x seeds, `[[grid]]`) or the leg
//! (scenarios x controllers x gains x patient presets or sampled patients x seeds,
//! `[[leg]]`); both go through the same runner, shards, resume and merge.
//!
//! Every run depends on its parameters only (its plant or patient, noise seed and gains),
//! never on the thread that runs it, so a sweep gives the same lines with any number of
//! threads, in any number of shards.
//!
//! ```toml
//! name = "example"
//! duration_s = 20.0
//! [[grid]]
//! controllers = ["aprc-ndo", "pid"]
//! gains = ["default"]                # or "paper", "tuned", "equal-activity/3", a file,
//!                                    # "aprc-ndo@paper+proxy_mass=5" (one controller, one gain changed)
//! references = ["sine", "chirp"]     # or "jump"
//! events = ["none"]                  # or "block", "impact-up", "impact-down"
//! seeds = [1, 2]                     # sensor-noise seeds (default: the plant's own)
//! [grid.plants]
//! presets = ["mismatch"]             # and/or a population:
//! added_load_kg = [0.0, 2.5]
//! [grid.plants.population]
//! size = 200
//! seed = 1
//! muscle_scale = [0.8, 1.2]
//! load_kg = [1.0, 5.0]
//! valve_lag_s = [0.0, 0.030]
//! noise_rms_m = [0.0, 20e-6]
//!
//! [[leg]]
//! scenarios = ["gait_training"]      # embedded names or scenario files
//! controllers = ["aprc-ndo", "pid"]
//! gains = ["leg"]                    # "leg" (shipped leg gains), "scenario", or as above
//! seeds = [1]                        # spasm and encoder-noise seeds (default: the scenario's)
//! [leg.patients]
//! presets = ["scenario", "severe"]   # the scenario's patient, or a spasticity preset
//! [leg.patients.population]
//! size = 20
//! seed = 1
//! spasticity = ["none", "severe"]
//! spasm_rate_per_min = [0.0, 6.0]
//! spasm_amplitude_nm = [5.0, 30.0]
//! effort_fraction = [-0.3, 0.1]
//! ```
use crate::StudyError;
use serde::{Deserialize, Serialize};
use std::path::Path;

mod bench;
mod embedded;
mod leg;
mod store;
pub mod summary;

pub use bench::{Grid, PlantSource, Plants, Point, RunRecord, Trace};
pub use leg::{
    LegGrid, LegPoint, LegRunRecord, PatientPopulation, PatientSource, Patients, Spasticity,
};
pub use store::{
    check_manifest, manifest, merge, read_runs, run_jobs, runs_jsonl, to_do, Manifest, Runs,
    RunsFile, Shard,
};
pub use summary::{markdown, summarise, GroupSummary, LegGroupSummary, Summary};

/// A sweep file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SweepFile {
    /// Name.
    pub name: String,
    /// One line.
    #[serde(default)]
    pub description: String,
    /// Simulated seconds per run.
    pub duration_s: f64,
    /// Control period of the bench's runs (s); a leg run keeps its scenario's.
    #[serde(default = "default_period")]
    pub period_s: f64,
    /// The bench's grids; the sweep is their union, in order.
    #[serde(default)]
    pub grid: Vec<Grid>,
    /// The leg's grids, after the bench's.
    #[serde(default)]
    pub leg: Vec<LegGrid>,
}

fn default_period() -> f64 {
    1e-3
}

/// Most runs a sweep may have (every run is expanded in memory before the first starts).
pub const MAX_RUNS: usize = 100_000;

/// One run of a sweep: on the bench or on the leg.
#[derive(Debug, Clone)]
pub enum Job {
    /// A run of the single-muscle bench.
    Bench(Point),
    /// A run of the leg.
    Leg(LegPoint),
}

impl Job {
    /// Position in the sweep (stable for a given file).
    pub fn index(&self) -> usize {
        match self {
            Job::Bench(p) => p.index,
            Job::Leg(p) => p.index,
        }
    }

    /// Runs it and returns its line.
    pub fn run(&self, file: &SweepFile) -> Result<Record, StudyError> {
        Ok(match self {
            Job::Bench(p) => Record::Bench(p.run(file.duration_s, file.period_s)?),
            Job::Leg(p) => Record::Leg(p.run(file.duration_s)?),
        })
    }

    /// Control periods it runs (for the wall-time estimate) and the estimated cost of one
    /// (s, release build).
    pub fn periods(&self, file: &SweepFile) -> (f64, f64) {
        match self {
            Job::Bench(_) => (file.duration_s / file.period_s, 1e-6),
            Job::Leg(p) => (file.duration_s / p.period_s(), 20e-6),
        }
    }

    /// What it runs, on one line (for messages).
    pub fn describe(&self) -> String {
        match self {
            Job::Bench(p) => format!(
                "{} ({}) on {} / {}",
                p.controller,
                p.gains,
                p.reference.name(),
                p.event.name()
            ),
            Job::Leg(p) => format!(
                "{} ({}) on {} with patient {}",
                p.controller,
                p.gains,
                p.scenario_name(),
                p.patient.label()
            ),
        }
    }
}

/// A run's line in `runs.jsonl`: a bench run's, a leg run's or a failed run's (told apart
/// by their fields, so a bench sweep's lines are what they were before the leg's existed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Record {
    /// A bench run.
    Bench(RunRecord),
    /// A leg run.
    Leg(LegRunRecord),
    /// A run that failed.
    Failed(FailedRecord),
}

/// A run that failed (its simulation left physical bounds, say): recorded like any run, so
/// that the sweep goes on, the summary counts it, and a resume does not run it again (a
/// run depends on its parameters only: it would fail the same way). A run the supervisor
/// stopped is not failed: its figures up to the fault are a result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FailedRecord {
    /// Index in the sweep.
    pub run: usize,
    /// What it ran: controller, gains and setting, as messages name it.
    pub ran: String,
    /// Scenario, as the sweep file names it (leg runs; `null` for a bench run).
    pub scenario: Option<String>,
    /// Why it failed.
    pub failed: String,
}

impl FailedRecord {
    /// `job` failed with `error`.
    pub fn of(job: &Job, error: &StudyError) -> Self {
        Self {
            run: job.index(),
            ran: job.describe(),
            scenario: match job {
                Job::Bench(_) => None,
                Job::Leg(p) => Some(p.scenario_name().to_owned()),
            },
            failed: error.to_string(),
        }
    }
}

impl Record {
    /// Index of the run in the sweep.
    pub fn run(&self) -> usize {
        match self {
            Record::Bench(r) => r.run,
            Record::Leg(r) => r.run,
            Record::Failed(r) => r.run,
        }
    }

    /// What it ran, on one line (for messages).
    fn describe(&self) -> String {
        match self {
            Record::Bench(r) => format!(
                "{} ({}) on {} / {}",
                r.controller, r.gains, r.reference, r.event
            ),
            Record::Leg(r) => format!(
                "{} ({}) on {} with patient {}",
                r.controller, r.gains, r.scenario, r.patient
            ),
            Record::Failed(r) => r.ran.clone(),
        }
    }

    /// The bench run, if it is one.
    pub fn bench(&self) -> Option<&RunRecord> {
        match self {
            Record::Bench(r) => Some(r),
            _ => None,
        }
    }

    /// The leg run, if it is one.
    pub fn leg(&self) -> Option<&LegRunRecord> {
        match self {
            Record::Leg(r) => Some(r),
            _ => None,
        }
    }

    /// The failed run, if it is one.
    pub fn failed(&self) -> Option<&FailedRecord> {
        match self {
            Record::Failed(r) => Some(r),
            _ => None,
        }
    }
}

/// A sweep ready to run.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The file's content.
    pub file: SweepFile,
    /// Every run, in order: the bench's grids, then the leg's.
    pub jobs: Vec<Job>,
    /// A fingerprint of the file: shards and resumed runs must come from the same one.
    pub fingerprint: String,
}

pub(crate) fn field_error(file: &str, field: &str, message: String) -> StudyError {
    StudyError::Parse {
        what: "sweep file",
        file: file.to_owned(),
        message: format!("{field}: {message}"),
    }
}

/// FNV-1a of the text: stable across platforms and versions.
fn fingerprint(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

impl Sweep {
    /// Parses and expands a sweep file; `file` names it in errors (and gain, scenario
    /// files are relative to `dir`).
    pub fn from_toml_str(text: &str, file: &str, dir: &Path) -> Result<Self, StudyError> {
        let parsed: SweepFile = toml::from_str(text).map_err(|e| StudyError::Parse {
            what: "sweep file",
            file: file.to_owned(),
            message: pma_control::text::toml_error(text, &e),
        })?;
        let spec = pma_bench::RunSpec {
            duration_s: parsed.duration_s,
            period_s: parsed.period_s,
            x_a_m: None,
        };
        spec.validate()
            .map_err(|e| field_error(file, "duration_s, period_s", e.to_string()))?;
        if parsed.grid.is_empty() && parsed.leg.is_empty() {
            return Err(field_error(
                file,
                "grid",
                "no [[grid]] nor [[leg]]: nothing to run".into(),
            ));
        }
        for (g, grid) in parsed.grid.iter().enumerate() {
            if let Some(p) = grid.plants.population {
                p.validate().map_err(|e| {
                    field_error(file, &format!("grid[{g}].plants.population"), e.to_string())
                })?;
            }
        }
        for (g, grid) in parsed.leg.iter().enumerate() {
            if let Some(p) = &grid.patients.population {
                p.validate().map_err(|e| {
                    field_error(
                        file,
                        &format!("leg[{g}].patients.population"),
                        e.to_string(),
                    )
                })?;
            }
        }
        let total = count_runs(&parsed).ok_or_else(|| {
            field_error(
                file,
                "grid",
                format!("more than {MAX_RUNS} runs: split the study into several sweep files"),
            )
        })?;
        let mut jobs = Vec::with_capacity(total);
        for (g, grid) in parsed.grid.iter().enumerate() {
            bench::expand(grid, file, dir, g, &mut jobs)?;
        }
        for (g, grid) in parsed.leg.iter().enumerate() {
            leg::expand(grid, parsed.duration_s, file, dir, g, &mut jobs)?;
        }
        if jobs.is_empty() {
            return Err(field_error(
                file,
                "grid",
                "the grid is empty (no controller takes any of the gain sets)".into(),
            ));
        }
        Ok(Self {
            fingerprint: fingerprint(text),
            file: parsed,
            jobs,
        })
    }

    /// Reads a sweep file.
    pub fn load(path: &Path) -> Result<Self, StudyError> {
        let text = std::fs::read_to_string(path).map_err(|e| StudyError::Io {
            operation: "read",
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Self::from_toml_str(&text, &path.display().to_string(), dir)
    }

    /// The bench's runs.
    pub fn bench_points(&self) -> impl Iterator<Item = &Point> {
        self.jobs.iter().filter_map(|j| match j {
            Job::Bench(p) => Some(p),
            Job::Leg(_) => None,
        })
    }
}

/// How many runs the file's grids have at most, counted without expanding them (their
/// sizes validated first); `None` above [`MAX_RUNS`] or on overflow.
fn count_runs(file: &SweepFile) -> Option<usize> {
    let bench = file.grid.iter().map(Grid::count);
    let leg = file.leg.iter().map(LegGrid::count);
    bench
        .chain(leg)
        .try_fold(0usize, |n, g| n.checked_add(g?))
        .filter(|&n| n <= MAX_RUNS)
}

/// The items of `list` by name among `all`; an unknown name is an error naming `field`.
pub(crate) fn names<T: Copy>(
    list: &[String],
    all: &[(T, &'static str)],
    file: &str,
    field: &str,
) -> Result<Vec<T>, StudyError> {
    list.iter()
        .map(|n| {
            all.iter()
                .find(|(_, name)| name == n)
                .map(|(k, _)| *k)
                .ok_or_else(|| {
                    let known: Vec<&str> = all.iter().map(|(_, n)| *n).collect();
                    field_error(
                        file,
                        field,
                        format!("unknown `{n}` (expected one of: {})", known.join(", ")),
                    )
                })
        })
        .collect()
}

/// The controllers by name.
pub(crate) fn controller_names() -> Vec<(pma_control::ControllerKind, &'static str)> {
    pma_control::ControllerKind::ALL
        .iter()
        .map(|k| (*k, k.as_str()))
        .collect()
}

/// The seeds of a grid: `None` (each plant's or scenario's own) when none is given.
pub(crate) fn seeds(list: &[u64]) -> Vec<Option<u64>> {
    if list.is_empty() {
        vec![None]
    } else {
        list.iter().copied().map(Some).collect()
    }
}

/// The shipped sweeps (`crates/pma-studies/models/sweeps/`).
pub const SHIPPED: [(&str, &str); 4] = [
    ("shocks", include_str!("../../models/sweeps/shocks.toml")),
    ("fig9", include_str!("../../models/sweeps/fig9.toml")),
    (
        "monte_carlo",
        include_str!("../../models/sweeps/monte_carlo.toml"),
    ),
    (
        "leg_patients",
        include_str!("../../models/sweeps/leg_patients.toml"),
    ),
];

/// A shipped sweep by name, or a sweep file (`.toml`).
pub fn load(name_or_path: &str) -> Result<Sweep, StudyError> {
    if let Some((name, text)) = SHIPPED.iter().find(|(n, _)| *n == name_or_path) {
        return Sweep::from_toml_str(
            text,
            &format!("crates/pma-studies/models/sweeps/{name}.toml"),
            Path::new("."),
        );
    }
    if !name_or_path.ends_with(".toml") {
        let names: Vec<&str> = SHIPPED.iter().map(|(n, _)| *n).collect();
        return Err(StudyError::Parse {
            what: "sweep",
            file: name_or_path.to_owned(),
            message: format!(
                "unknown sweep (expected {} or a .toml file)",
                names.join(", ")
            ),
        });
    }
    Sweep::load(Path::new(name_or_path))
}
