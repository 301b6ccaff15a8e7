//! The bench's grids (`[[grid]]`): controllers x gains x plants or sampled plant
//! populations x references x events x seeds, each run one line of figures.
use super::{controller_names, embedded, field_error, names, seeds, Job};
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
use std::path::Path;

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
impl Grid {
    /// How many runs the grid has at most (a gain set that does not apply to a controller
    /// is skipped later), counted without expanding it; `None` on overflow.
    pub(super) fn count(&self) -> Option<usize> {
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

/// Appends the runs of bench grid `g` to `jobs`.
pub(super) fn expand(
    grid: &Grid,
    file: &str,
    dir: &Path,
    g: usize,
    jobs: &mut Vec<Job>,
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
    let seeds = seeds(&grid.seeds);
    for plant in &plants {
        for &controller in &controllers {
            for gains in &grid.gains {
                let Some(config) = embedded::gains_for(controller, gains, dir, None)
                    .map_err(|m| field_error(file, &grid_field("gains"), m))?
                else {
                    continue;
                };
                for &reference in &references {
                    for &event in &events {
                        for &seed in &seeds {
                            jobs.push(Job::Bench(Point {
                                index: jobs.len(),
                                controller,
                                gains: gains.clone(),
                                config,
                                plant: plant.clone(),
                                reference,
                                event,
                                seed,
                            }));
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// A bench run's line in `runs.jsonl`: its parameters and its figures (nothing that
/// depends on the machine or the thread, so the lines are reproducible).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
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
