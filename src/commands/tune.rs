//! `pma-exo tune` and `pma-exo tune-leg`: the firefly search over a controller's gains.
use super::check_duration;
use super::simulate::LEG_PERIOD_S;
use crate::output::{self, OutFile};
use crate::say;
use anyhow::{bail, Result};
use pma_control::ControllerKind;
use std::path::PathBuf;

/// `tune`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The controller to tune.
    #[arg(long, value_name = crate::CONTROLLERS)]
    controller: ControllerKind,
    /// Plant the gains are tuned on (preset or .toml file).
    #[arg(long, default_value = "mismatch")]
    plant: String,
    /// Fireflies.
    #[arg(long, default_value_t = 20)]
    population: usize,
    /// Generations.
    #[arg(long, default_value_t = 40)]
    generations: usize,
    /// Simulated seconds per evaluation.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    duration: f64,
    /// Optimiser seed.
    #[arg(long, default_value_t = 2019)]
    seed: u64,
    /// Budget on command activity: mean |du/dt| of the pressure command (bar/s).
    #[arg(long, value_name = "BAR_PER_S", allow_negative_numbers = true)]
    max_variation: Option<f64>,
    /// Write the gain file here (created before the search; printed otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Worker threads (default: one per core); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

impl Args {
    /// The command line that reproduces a tuning (written into the gain file).
    fn command(&self, plant: &str) -> String {
        let budget = self
            .max_variation
            .map_or(String::new(), |v| format!(" --max-variation {v}"));
        format!(
            "pma-exo tune --controller {} --plant {plant} --population {} --generations {} --duration {} --seed {}{budget}",
            self.controller, self.population, self.generations, self.duration, self.seed
        )
    }
}

/// Evaluations of a firefly search: the initial population, then every pair per generation
/// at most (the tuner's own count is reported after the run).
fn evaluations(population: usize, generations: usize) -> f64 {
    (population + population * generations) as f64
}

fn check_population(population: usize) -> Result<()> {
    if population < 2 {
        bail!("--population must be at least 2 (got {population})");
    }
    Ok(())
}

/// Runs `tune`.
pub fn run(a: Args) -> Result<i32> {
    check_duration(a.duration)?;
    check_population(a.population)?;
    if let Some(v) = a.max_variation {
        if !(v.is_finite() && v > 0.0) {
            bail!("--max-variation must be a finite number of bar/s > 0 (got {v})");
        }
    }
    let plant = pma_sim::PlantConfig::load(&a.plant)?;
    let spec = pma_sim::RunSpec {
        duration_s: a.duration,
        ..Default::default()
    };
    let periods = spec.settings()?.periods() as f64;
    output::check_wall_time(
        "this tuning",
        periods * evaluations(a.population, a.generations),
        1e-6,
        a.yes,
    )?;
    let out = a.out.as_deref().map(OutFile::create).transpose()?;
    let opts = pma_sim::tune::FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        ..Default::default()
    };
    let objective = pma_sim::tune::Objective {
        duration_s: a.duration,
        max_variation_pa_per_s: a.max_variation.map(|v| v * 1e5),
    };
    let found = super::with_threads(a.threads, || {
        pma_sim::tune::tune(a.controller, &plant, &opts, &objective)
    })?;
    let Some(res) = found else {
        bail!(
            "{} has no search space here (pass --gains to change its gains)",
            a.controller
        );
    };
    let (iae, var) = (res.score.iae_m, res.score.variation_pa_per_s / 1e5);
    if !res.feasible {
        bail!(
            "{}: no gain set within the budget found after {} runs (best: {var:.2} bar/s, IAE {iae:.4e} m)",
            a.controller,
            res.evaluations
        );
    }
    let text = format!(
        "# Tuned by `{}`\n# ({} runs, sine IAE {iae:.4e} m, command variation {var:.3} bar/s)\n{}",
        a.command(&plant.name),
        res.evaluations,
        res.config.to_toml_string()
    );
    write_gain_file(out, &text)?;
    eprintln!(
        "{}: IAE {iae:.4e} m, {var:.3} bar/s after {} runs",
        a.controller, res.evaluations
    );
    Ok(0)
}

/// `tune-leg`'s arguments.
#[derive(clap::Args)]
pub struct LegArgs {
    /// An embedded scenario or a scenario .toml file.
    #[arg(default_value = "gait_training")]
    scenario: String,
    /// The controller to tune (one gain set for the four muscles).
    #[arg(long, value_name = crate::CONTROLLERS, default_value = "aprc-ndo")]
    controller: ControllerKind,
    /// Fireflies.
    #[arg(long, default_value_t = 20)]
    population: usize,
    /// Generations.
    #[arg(long, default_value_t = 25)]
    generations: usize,
    /// Simulated seconds per evaluation; at least two strides.
    #[arg(long, default_value_t = 6.4, allow_negative_numbers = true)]
    duration: f64,
    /// Optimiser seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the gain file here (created before the search; printed otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Worker threads (default: one per core); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// Runs `tune-leg`.
pub fn run_leg(a: LegArgs) -> Result<i32> {
    check_duration(a.duration)?;
    check_population(a.population)?;
    let loaded = pma_leg::Scenario::load(&a.scenario)?;
    let sc = &loaded.scenario;
    sc.check_run_duration(a.duration)?;
    output::check_wall_time(
        "this tuning",
        a.duration / sc.period_s * evaluations(a.population, a.generations),
        LEG_PERIOD_S,
        a.yes,
    )?;
    let out = a.out.as_deref().map(OutFile::create).transpose()?;
    let opts = pma_sim::tune::FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        ..Default::default()
    };
    let found = super::with_threads(a.threads, || {
        pma_leg::tune::tune(&loaded, a.controller, &opts, a.duration)
    })?;
    let Some(t) = found else {
        bail!(
            "{} has no search space here (pass --gains to simulate to change its gains)",
            a.controller
        );
    };
    if t.objective >= pma_leg::tune::FAILED_RUN {
        bail!(
            "every one of the {} runs failed or went non-finite: no gains to report",
            t.evaluations
        );
    }
    let text = format!(
        "# Tuned by `pma-exo tune-leg {} --controller {} --population {} --generations {} --duration {} --seed {}`\n# ({} runs, objective {:.4}: hip RMS + knee RMS in deg + 0.01 x bar/s)\n{}",
        a.scenario,
        a.controller,
        a.population,
        a.generations,
        a.duration,
        a.seed,
        t.evaluations,
        t.objective,
        t.config.to_toml_string()
    );
    write_gain_file(out, &text)?;
    eprintln!(
        "{}: objective {:.4} after {} runs",
        a.controller, t.objective, t.evaluations
    );
    Ok(0)
}

/// The gain file's text to `out`, or to stdout without `--out`.
fn write_gain_file(out: Option<OutFile>, text: &str) -> Result<()> {
    match out {
        Some(f) => f.finish_with(text),
        None => {
            say!("{}", text.trim_end());
            Ok(())
        }
    }
}
