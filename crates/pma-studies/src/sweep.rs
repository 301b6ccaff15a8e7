//! Sweeps: a TOML-described grid of bench runs (controllers x gains x plants or sampled
//! plant populations x references x events x seeds), run in parallel, each run's
//! parameters and figures one JSON line of `runs.jsonl`; shards for cluster job arrays,
//! resumption after a kill, merging and a summary.
//!
//! Every run depends on its parameters only (its plant, noise seed and gains), never on
//! the thread that runs it, so a sweep gives the same lines with any number of threads, in
//! any number of shards.
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
//! ```
use crate::files::{dir_error, read_error, write_atomically, write_error};
use crate::population::Population;
use crate::shock::{Event, EventMetrics, EventRecorder, RefKind};
use crate::StudyError;
use pma_bench::{MuscleBench, PlantConfig, RunSpec};
use pma_control::{
    CommandLimits, ControllerConfig, ControllerKind, MuscleStep, MuscleTask, Tracking,
    TrackingStats,
};
use pma_loop::{Period, Recorder};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};

mod embedded;
pub mod summary;

pub use summary::{markdown, summarise, GroupSummary, Summary};

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
    /// Control period (s).
    #[serde(default = "default_period")]
    pub period_s: f64,
    /// The grids; the sweep is their union, in order.
    pub grid: Vec<Grid>,
}

fn default_period() -> f64 {
    1e-3
}

/// One grid of a sweep file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Controller names.
    pub controllers: Vec<String>,
    /// Gain sets (see the module documentation); a pair that does not apply is skipped.
    pub gains: Vec<String>,
    /// Plants.
    pub plants: Plants,
    /// References.
    pub references: Vec<String>,
    /// Events.
    #[serde(default = "default_events")]
    pub events: Vec<String>,
    /// Sensor-noise seeds; absent: each plant's own.
    #[serde(default)]
    pub seeds: Vec<u64>,
}

/// Most runs a sweep may have (every run is expanded in memory before the first starts).
pub const MAX_RUNS: usize = 100_000;

impl Grid {
    /// How many runs the grid has at most (a gain set that does not apply to a controller
    /// is skipped later), counted without expanding it; `None` on overflow.
    fn count(&self) -> Option<usize> {
        let population = self.plants.population.map_or(0, |p| p.size);
        let plants = self
            .plants
            .presets
            .len()
            .checked_mul(self.plants.added_load_kg.len())?
            .checked_add(population)?;
        [
            self.controllers.len(),
            self.gains.len(),
            self.references.len(),
            self.events.len(),
            self.seeds.len().max(1),
        ]
        .iter()
        .try_fold(plants, |n, &k| n.checked_mul(k))
    }
}

fn default_events() -> Vec<String> {
    vec!["none".into()]
}

/// The plants of a grid.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Plants {
    /// Presets or plant files.
    #[serde(default)]
    pub presets: Vec<String>,
    /// Mass added to every preset's load, one plant per value (kg).
    #[serde(default = "no_added_load")]
    pub added_load_kg: Vec<f64>,
    /// A sampled population.
    #[serde(default)]
    pub population: Option<Population>,
}

fn no_added_load() -> Vec<f64> {
    vec![0.0]
}

/// Where a run's plant comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum PlantSource {
    /// A preset or file, with mass added to its load.
    Preset {
        /// The plant.
        plant: Box<PlantConfig>,
        /// Added mass (kg).
        added_load_kg: f64,
    },
    /// Plant `index` of a population.
    Population {
        /// The ranges.
        population: Population,
        /// Which plant.
        index: usize,
    },
}

/// One run of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Position in the sweep (stable for a given file).
    pub index: usize,
    /// Controller.
    pub controller: ControllerKind,
    /// The gain set's name in the file.
    pub gains: String,
    /// The gains.
    pub config: ControllerConfig,
    /// The plant.
    pub plant: PlantSource,
    /// Reference.
    pub reference: RefKind,
    /// Event.
    pub event: Event,
    /// Sensor-noise seed, if set by the sweep.
    pub seed: Option<u64>,
}

/// A sweep ready to run.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The file's content.
    pub file: SweepFile,
    /// Every run, in order.
    pub points: Vec<Point>,
    /// A fingerprint of the file: shards and resumed runs must come from the same one.
    pub fingerprint: String,
}

fn field_error(file: &str, field: &str, message: String) -> StudyError {
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
    /// Parses and expands a sweep file; `file` names it in errors (and gain files are
    /// relative to `dir`).
    pub fn from_toml_str(text: &str, file: &str, dir: &Path) -> Result<Self, StudyError> {
        let parsed: SweepFile = toml::from_str(text).map_err(|e| StudyError::Parse {
            what: "sweep file",
            file: file.to_owned(),
            message: pma_control::text::toml_error(text, &e),
        })?;
        let spec = RunSpec {
            duration_s: parsed.duration_s,
            period_s: parsed.period_s,
            x_a_m: None,
        };
        spec.validate()
            .map_err(|e| field_error(file, "duration_s, period_s", e.to_string()))?;
        if parsed.grid.is_empty() {
            return Err(field_error(
                file,
                "grid",
                "no [[grid]]: nothing to run".into(),
            ));
        }
        for (g, grid) in parsed.grid.iter().enumerate() {
            if let Some(p) = grid.plants.population {
                p.validate().map_err(|e| {
                    field_error(file, &format!("grid[{g}].plants.population"), e.to_string())
                })?;
            }
        }
        let total = parsed
            .grid
            .iter()
            .try_fold(0usize, |n, g| n.checked_add(g.count()?))
            .filter(|&n| n <= MAX_RUNS)
            .ok_or_else(|| {
                field_error(
                    file,
                    "grid",
                    format!("more than {MAX_RUNS} runs: split the study into several sweep files"),
                )
            })?;
        let mut points = Vec::with_capacity(total);
        for (g, grid) in parsed.grid.iter().enumerate() {
            expand(grid, file, dir, g, &mut points)?;
        }
        if points.is_empty() {
            return Err(field_error(
                file,
                "grid",
                "the grid is empty (no controller takes any of the gain sets)".into(),
            ));
        }
        Ok(Self {
            fingerprint: fingerprint(text),
            file: parsed,
            points,
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
}

fn names<T: Copy>(
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

fn plants(grid: &Grid, file: &str) -> Result<Vec<PlantSource>, StudyError> {
    let mut out = Vec::new();
    for name in &grid.plants.presets {
        let plant = PlantConfig::load(name)
            .map_err(|e| field_error(file, "plants.presets", e.to_string()))?;
        for &added in &grid.plants.added_load_kg {
            if !(added.is_finite() && added >= 0.0) {
                return Err(field_error(
                    file,
                    "plants.added_load_kg",
                    format!("{added} is not a mass >= 0"),
                ));
            }
            out.push(PlantSource::Preset {
                plant: Box::new(plant.clone()),
                added_load_kg: added,
            });
        }
    }
    if let Some(p) = grid.plants.population {
        p.validate()
            .map_err(|e| field_error(file, "plants.population", e.to_string()))?;
        out.extend((0..p.size).map(|index| PlantSource::Population {
            population: p,
            index,
        }));
    }
    if out.is_empty() {
        return Err(field_error(
            file,
            "plants",
            "no plant (give presets or a population)".into(),
        ));
    }
    Ok(out)
}

fn expand(
    grid: &Grid,
    file: &str,
    dir: &Path,
    g: usize,
    points: &mut Vec<Point>,
) -> Result<(), StudyError> {
    let grid_field = |f: &str| format!("grid[{g}].{f}");
    let controllers = names(
        &grid.controllers,
        &controller_names(),
        file,
        &grid_field("controllers"),
    )?;
    let references = names(
        &grid.references,
        &RefKind::ALL,
        file,
        &grid_field("references"),
    )?;
    let events = names(&grid.events, &Event::ALL, file, &grid_field("events"))?;
    for (field, empty) in [
        ("controllers", controllers.is_empty()),
        ("gains", grid.gains.is_empty()),
        ("references", references.is_empty()),
        ("events", events.is_empty()),
    ] {
        if empty {
            return Err(field_error(
                file,
                &grid_field(field),
                "empty: nothing to run".into(),
            ));
        }
    }
    let plants = plants(grid, file)?;
    let seeds: Vec<Option<u64>> = if grid.seeds.is_empty() {
        vec![None]
    } else {
        grid.seeds.iter().copied().map(Some).collect()
    };
    for plant in &plants {
        for &controller in &controllers {
            for gains in &grid.gains {
                let Some(config) = embedded::gains_for(controller, gains, dir)
                    .map_err(|m| field_error(file, &grid_field("gains"), m))?
                else {
                    continue;
                };
                for &reference in &references {
                    for &event in &events {
                        for &seed in &seeds {
                            points.push(Point {
                                index: points.len(),
                                controller,
                                gains: gains.clone(),
                                config,
                                plant: plant.clone(),
                                reference,
                                event,
                                seed,
                            });
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

fn controller_names() -> Vec<(ControllerKind, &'static str)> {
    ControllerKind::ALL
        .iter()
        .map(|k| (*k, k.as_str()))
        .collect()
}

/// A run's line in `runs.jsonl`: its parameters and its figures (nothing that depends on
/// the machine or the thread, so the lines are reproducible).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// Index in the sweep.
    pub run: usize,
    /// Controller.
    pub controller: String,
    /// Gain set.
    pub gains: String,
    /// Plant (`mismatch`, `mismatch+2.5kg`, `population-17`).
    pub plant: String,
    /// Group of the plant (`mismatch`, `mismatch+2.5kg`, `population`).
    pub plant_group: String,
    /// True load mass (kg).
    pub load_kg: f64,
    /// Valve time constant (s).
    pub valve_lag_s: f64,
    /// Sensor noise (m RMS).
    pub noise_rms_m: f64,
    /// Reference.
    pub reference: String,
    /// Event.
    pub event: String,
    /// Sensor-noise seed used.
    pub seed: u64,
    /// MAE, eq. (51) (m).
    pub mae_m: f64,
    /// IAE, eq. (52): mean |e| (m).
    pub iae_m: f64,
    /// RTE, eq. (53) (%).
    pub rte_percent: f64,
    /// RMS error (m).
    pub rms_m: f64,
    /// Command variation (bar/s).
    pub command_variation_bar_per_s: f64,
    /// Share of the run with the command at 0 or the valve's maximum.
    pub limit_fraction: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
    /// Per event.
    pub events: Vec<EventMetrics>,
}

/// Time at the valve's limits.
struct Limits {
    limit_periods: u64,
    periods: u64,
    pressure_max_pa: f64,
}

impl Recorder<MuscleBench, MuscleStep> for Limits {
    fn record(&mut self, p: &Period<'_, MuscleBench, MuscleStep>) {
        let u = p.output.control.pressure_cmd_pa;
        self.periods += 1;
        if u <= 0.0 || u >= self.pressure_max_pa {
            self.limit_periods += 1;
        }
    }
}

/// What a bench run of a sweep measured.
struct Figures {
    tracking: Tracking<MuscleBench>,
    limits: Limits,
    events: EventRecorder,
    ran_s: f64,
}

impl Point {
    /// The plant, its name and group.
    pub fn resolve_plant(&self) -> Result<(PlantConfig, String, String), StudyError> {
        let (mut plant, name, group) = match &self.plant {
            PlantSource::Preset {
                plant,
                added_load_kg,
            } => {
                let mut p = (**plant).clone();
                let label = if *added_load_kg > 0.0 {
                    format!("{}+{added_load_kg}kg", p.name)
                } else {
                    p.name.clone()
                };
                p.load.mass_kg += added_load_kg;
                (p, label.clone(), label)
            }
            PlantSource::Population { population, index } => {
                let p = population.plant(*index)?;
                let name = p.name.clone();
                (p, name, "population".into())
            }
        };
        if let Some(seed) = self.seed {
            plant.sensor.seed = seed;
        }
        Ok((plant, name, group))
    }

    /// Runs it through the loop of `pma-loop` on the bench, `extra` observing.
    fn simulate<R: Recorder<MuscleBench, MuscleStep>>(
        &self,
        duration_s: f64,
        period_s: f64,
        extra: &mut R,
    ) -> Result<(PlantConfig, String, String, Figures), StudyError> {
        let (plant, name, group) = self.resolve_plant()?;
        let reference = self.reference.reference();
        let spec = RunSpec {
            duration_s,
            period_s,
            x_a_m: None,
        };
        let settings = spec.settings()?;
        let limits = CommandLimits {
            min_pa: 0.0,
            max_pa: plant.valve.pressure_max_pa,
        };
        let controller =
            pma_control::build_controller(&self.config, plant.nominal_model(), limits)?;
        let mut bench = MuscleBench::at_rest(&plant, reference.sample(0.0).position_m)?
            .with_disturbance(self.event.disturbance())
            .with_period(period_s);
        let mut task = MuscleTask::new(controller, reference.as_ref());
        let mut tracking = Tracking::<MuscleBench>::new(|_, truth| truth.position_m);
        let mut limits_at = Limits {
            limit_periods: 0,
            periods: 0,
            pressure_max_pa: limits.max_pa,
        };
        let mut events = EventRecorder::new(self.reference, self.event, limits.max_pa);
        let outcome = pma_loop::run(
            &mut bench,
            &mut task,
            &mut (&mut tracking, &mut limits_at, &mut events, extra),
            &settings,
        )?;
        let figures = Figures {
            tracking,
            limits: limits_at,
            events,
            ran_s: outcome.ran_s,
        };
        Ok((plant, name, group, figures))
    }

    /// Runs it and returns its line.
    pub fn run(&self, duration_s: f64, period_s: f64) -> Result<RunRecord, StudyError> {
        let (plant, name, group, figures) = self.simulate(duration_s, period_s, &mut ())?;
        let s = figures.tracking.summary(figures.ran_s, None);
        let stats: TrackingStats = s.stats;
        Ok(RunRecord {
            run: self.index,
            controller: self.controller.as_str().to_owned(),
            gains: self.gains.clone(),
            plant: name,
            plant_group: group,
            load_kg: plant.load.mass_kg,
            valve_lag_s: plant.valve.time_constant_s,
            noise_rms_m: plant.sensor.noise_rms_m,
            reference: self.reference.name().to_owned(),
            event: self.event.name().to_owned(),
            seed: plant.sensor.seed,
            mae_m: stats.mae_m,
            iae_m: stats.iae_m,
            rte_percent: stats.rte_percent,
            rms_m: stats.rms_m,
            command_variation_bar_per_s: s.command_variation_pa_per_s / 1e5,
            limit_fraction: figures.limits.limit_periods as f64
                / figures.limits.periods.max(1) as f64,
            finite: s.finite,
            events: figures.events.metrics(),
        })
    }

    /// Runs it and returns its trajectories over `[from_s, to_s]`, one sample every
    /// `every` periods (for plots).
    pub fn trace(
        &self,
        duration_s: f64,
        period_s: f64,
        (from_s, to_s): (f64, f64),
        every: u64,
    ) -> Result<Trace, StudyError> {
        let mut rec = TraceRecorder {
            trace: Trace {
                label: format!("{} ({})", self.controller, self.gains),
                ..Trace::default()
            },
            from_s,
            to_s,
            every: every.max(1),
        };
        self.simulate(duration_s, period_s, &mut rec)?;
        Ok(rec.trace)
    }
}

/// One run's trajectories around its events.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// Controller (gains).
    pub label: String,
    /// Time (s).
    pub t_s: Vec<f64>,
    /// Reference (m).
    pub reference_m: Vec<f64>,
    /// True position (m).
    pub position_m: Vec<f64>,
    /// Proxy position (m; NaN for controllers without one).
    pub proxy_m: Vec<f64>,
    /// Pressure command (Pa).
    pub command_pa: Vec<f64>,
    /// Obstacle contact force (N).
    pub contact_force_n: Vec<f64>,
}

struct TraceRecorder {
    trace: Trace,
    from_s: f64,
    to_s: f64,
    every: u64,
}

impl Recorder<MuscleBench, MuscleStep> for TraceRecorder {
    fn record(&mut self, p: &Period<'_, MuscleBench, MuscleStep>) {
        if p.t_s < self.from_s || p.t_s > self.to_s || !p.index.is_multiple_of(self.every) {
            return;
        }
        let t = &mut self.trace;
        t.t_s.push(p.t_s);
        t.reference_m.push(p.output.reference.position_m);
        t.position_m.push(p.truth.position_m);
        t.proxy_m
            .push(p.output.control.diagnostics.proxy_position_m);
        t.command_pa.push(p.output.control.pressure_cmd_pa);
        t.contact_force_n.push(p.truth.contact_force_n);
    }
}

/// The `I`-th of `N` disjoint parts of a sweep (`--shard I/N`, 1-based): the runs whose
/// index is `I - 1` modulo `N`, so that every part gets a share of every grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// Which part, from 1.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Default for Shard {
    fn default() -> Self {
        Self { index: 1, count: 1 }
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("`{s}` is not a shard: expected I/N with 1 <= I <= N (e.g. 2/8)");
        let (i, n) = s.split_once('/').ok_or_else(err)?;
        let (index, count): (usize, usize) =
            (i.parse().map_err(|_| err())?, n.parse().map_err(|_| err())?);
        if index == 0 || count == 0 || index > count {
            return Err(err());
        }
        Ok(Self { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Whether run `index` belongs to this part.
    pub fn contains(&self, index: usize) -> bool {
        index % self.count == self.index - 1
    }
}

/// What an output directory says it holds (`sweep.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Sweep name.
    pub name: String,
    /// Fingerprint of the sweep file.
    pub fingerprint: String,
    /// Runs in the whole sweep.
    pub runs: usize,
    /// This directory's part.
    pub shard: Shard,
}

/// The complete lines of a `runs.jsonl` (a torn last line, from a kill, is cut off the
/// file so that it is redone), by run index. Only indices below `runs_in_sweep` belong to
/// the sweep; a run recorded twice must be recorded the same way (runs are
/// deterministic: two different lines for one run mean two different sweeps wrote here).
pub fn read_runs(
    path: &Path,
    repair: bool,
    runs_in_sweep: usize,
) -> Result<BTreeMap<usize, RunRecord>, StudyError> {
    let mut runs = BTreeMap::new();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(runs),
        Err(e) => return Err(read_error(path, e)),
    };
    let mut good_bytes = 0usize;
    let mut offset = 0usize;
    for (number, line) in text.split_inclusive('\n').enumerate() {
        offset += line.len();
        let complete = line.ends_with('\n');
        match serde_json::from_str::<RunRecord>(line.trim_end()) {
            Ok(r) if complete => {
                add_run(
                    path,
                    &format!("line {}", number + 1),
                    r,
                    runs_in_sweep,
                    &mut runs,
                )?;
                good_bytes = offset;
            }
            _ if offset == text.len() && repair => break,
            _ => {
                return Err(dir_error(
                    path,
                    format!("line {} is not a run record", number + 1),
                ))
            }
        }
    }
    if repair && good_bytes < text.len() {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| write_error(path, e))?;
        f.set_len(good_bytes as u64)
            .map_err(|e| write_error(path, e))?;
    }
    Ok(runs)
}

fn add_run(
    path: &Path,
    at: &str,
    r: RunRecord,
    runs_in_sweep: usize,
    runs: &mut BTreeMap<usize, RunRecord>,
) -> Result<(), StudyError> {
    if r.run >= runs_in_sweep {
        return Err(dir_error(
            path,
            format!(
                "{at} records run {}, but the sweep has runs 0..{}: not a record of this sweep",
                r.run,
                runs_in_sweep.saturating_sub(1)
            ),
        ));
    }
    match runs.get(&r.run) {
        Some(seen) if *seen != r => Err(dir_error(
            path,
            format!(
                "{at} records run {} differently from an earlier record: two sweeps wrote here",
                r.run
            ),
        )),
        Some(_) => Ok(()),
        None => {
            runs.insert(r.run, r);
            Ok(())
        }
    }
}

/// Holds a directory for one sweep at a time (an advisory lock on `DIR/.lock`, released
/// when the process ends, even by a kill).
pub struct DirLock(#[allow(dead_code)] std::fs::File);

impl DirLock {
    /// Takes the lock of `out`, or fails at once if another process holds it.
    pub fn take(out: &Path) -> Result<Self, StudyError> {
        let path = out.join(".lock");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| write_error(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(Self(file)),
            Err(std::fs::TryLockError::WouldBlock) => Err(dir_error(
                out,
                "another `pma-exo sweep` is writing into this directory: wait for it or use another --out",
            )),
            Err(std::fs::TryLockError::Error(e)) => Err(write_error(&path, e)),
        }
    }
}

/// How an execution went.
#[derive(Debug, Clone, PartialEq)]
pub struct Execution {
    /// Runs of this shard.
    pub selected: usize,
    /// Of which already in the file (resumed).
    pub already_done: usize,
    /// Run now.
    pub run_now: usize,
}

/// Runs this shard of `sweep` into `out` (`runs.jsonl`, `sweep.json`), on the current
/// rayon pool, skipping the runs already written there; `progress(done, total)` is called
/// after each run. Once `stop` is raised no new run starts (the runs written stay; the
/// same command resumes).
pub fn execute(
    sweep: &Sweep,
    out: &Path,
    shard: Shard,
    progress: &(dyn Fn(usize, usize) + Sync),
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Execution, StudyError> {
    use rayon::prelude::*;
    std::fs::create_dir_all(out).map_err(|e| write_error(out, e))?;
    let manifest = Manifest {
        name: sweep.file.name.clone(),
        fingerprint: sweep.fingerprint.clone(),
        runs: sweep.points.len(),
        shard,
    };
    let _lock = DirLock::take(out)?;
    check_manifest(out, &manifest)?;
    let runs_path = out.join("runs.jsonl");
    let done = read_runs(&runs_path, true, sweep.points.len())?;
    for r in done.values() {
        check_record(&runs_path, r, &sweep.points[r.run])?;
    }
    let todo: Vec<&Point> = sweep
        .points
        .iter()
        .filter(|p| shard.contains(p.index) && !done.contains_key(&p.index))
        .collect();
    let selected = sweep
        .points
        .iter()
        .filter(|p| shard.contains(p.index))
        .count();
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&runs_path)
        .map_err(|e| write_error(&runs_path, e))?;
    let writer = std::sync::Mutex::new(file);
    let counter = std::sync::atomic::AtomicUsize::new(0);
    let total = todo.len();
    todo.par_iter()
        .try_for_each(|p| -> Result<(), StudyError> {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                return Ok(());
            }
            let record = p.run(sweep.file.duration_s, sweep.file.period_s)?;
            let mut line =
                serde_json::to_string(&record).map_err(|e| write_error(&runs_path, e))?;
            line.push('\n');
            {
                let mut f = writer.lock().unwrap_or_else(|e| e.into_inner());
                // One write per line: a kill tears at most the line being written.
                f.write_all(line.as_bytes())
                    .map_err(|e| write_error(&runs_path, e))?;
            }
            let n = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, total);
            Ok(())
        })?;
    Ok(Execution {
        selected,
        already_done: selected - total,
        run_now: counter.into_inner(),
    })
}

fn check_manifest(out: &Path, manifest: &Manifest) -> Result<(), StudyError> {
    let path = out.join("sweep.json");
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let found: Manifest = serde_json::from_str(&text).map_err(|e| dir_error(&path, e))?;
            if &found != manifest {
                return Err(dir_error(
                    &path,
                    format!(
                        "this directory holds shard {} of sweep `{}` ({}), not shard {} of `{}` ({}): use another --out",
                        found.shard, found.name, found.fingerprint, manifest.shard, manifest.name, manifest.fingerprint
                    ),
                ));
            }
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let text = serde_json::to_string_pretty(manifest).map_err(|e| write_error(&path, e))?;
            write_atomically(&path, &text)
        }
        Err(e) => Err(read_error(&path, e)),
    }
}

/// A recorded run must be the sweep's point of that index (the same controller, gains,
/// reference and event): a record from another sweep is refused.
fn check_record(path: &Path, r: &RunRecord, p: &Point) -> Result<(), StudyError> {
    let same = r.controller == p.controller.as_str()
        && r.gains == p.gains
        && r.reference == p.reference.name()
        && r.event == p.event.name();
    if same {
        Ok(())
    } else {
        Err(dir_error(
            path,
            format!(
                "run {} is recorded as {} ({}) on {} / {}, but the sweep's run {} is {} ({}) on {} / {}: not a record of this sweep",
                r.run, r.controller, r.gains, r.reference, r.event, p.index, p.controller, p.gains, p.reference.name(), p.event.name()
            ),
        ))
    }
}

/// Runs by index.
pub type Runs = BTreeMap<usize, RunRecord>;

/// Joins the shards in `dirs` (one sweep, any shards): their runs by index, checked
/// for coming from the same sweep file; the indices still missing are reported.
pub fn merge(dirs: &[PathBuf]) -> Result<(Manifest, Runs, Vec<usize>), StudyError> {
    let mut first: Option<Manifest> = None;
    let mut runs = BTreeMap::new();
    let mut shards = BTreeSet::new();
    for dir in dirs {
        let path = dir.join("sweep.json");
        let text = std::fs::read_to_string(&path).map_err(|e| read_error(&path, e))?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| dir_error(&path, e))?;
        if let Some(f) = &first {
            if f.fingerprint != m.fingerprint || f.runs != m.runs {
                return Err(dir_error(
                    &path,
                    format!(
                        "holds sweep `{}` ({}), not `{}` ({})",
                        m.name, m.fingerprint, f.name, f.fingerprint
                    ),
                ));
            }
        }
        shards.insert(m.shard.index);
        let path = dir.join("runs.jsonl");
        for (index, r) in read_runs(&path, false, m.runs)? {
            add_run(&path, &format!("run {index}"), r, m.runs, &mut runs)?;
        }
        first.get_or_insert(m);
    }
    let manifest = first.ok_or_else(|| dir_error(Path::new("."), "no directory to merge"))?;
    let missing: Vec<usize> = (0..manifest.runs)
        .filter(|i| !runs.contains_key(i))
        .collect();
    Ok((manifest, runs, missing))
}

/// Writes `runs.jsonl` sorted by index.
pub fn write_runs(path: &Path, runs: &BTreeMap<usize, RunRecord>) -> Result<(), StudyError> {
    let mut text = String::new();
    for r in runs.values() {
        text.push_str(&serde_json::to_string(r).map_err(|e| write_error(path, e))?);
        text.push('\n');
    }
    write_atomically(path, &text)
}

/// The shipped sweeps (`crates/pma-studies/models/sweeps/`).
pub const SHIPPED: [(&str, &str); 3] = [
    ("shocks", include_str!("../models/sweeps/shocks.toml")),
    ("fig9", include_str!("../models/sweeps/fig9.toml")),
    (
        "monte_carlo",
        include_str!("../models/sweeps/monte_carlo.toml"),
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
