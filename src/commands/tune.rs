//! `pma-exo tune` and `pma-exo tune-leg`: the firefly search over a controller's gains.
use super::check_duration;
use super::simulate::LEG_PERIOD_S;
use crate::output::{self, OutFile};
use crate::say;
use anyhow::{bail, Context, Result};
use pma_control::ControllerKind;
use std::path::PathBuf;

/// `tune`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The controller to tune.
    #[arg(long, value_name = ControllerKind::NAMES)]
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
    /// Robust tuning: score every gain set on this many plants drawn around `--plant`
    /// (each muscle scale, the load and the valve's lag times a factor in
    /// 1 +- `--spread`; the controllers' nominal kept), combined by `--objective`.
    #[arg(long, value_name = "N")]
    robust: Option<usize>,
    /// Half-width of the robust plants' factors (0..=0.5).
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    spread: f64,
    /// How a robust tuning combines its plants' scores.
    #[arg(long, value_enum, default_value = "mean")]
    objective: ObjectiveArg,
    /// Robust tuning on plants drawn from a sweep's population ranges instead (a shipped
    /// sweep such as `monte_carlo`, or a file), with `--seed` (which must differ from the
    /// sweep's, so the tuning does not see the plants the sweep scores).
    #[arg(long, value_name = "SWEEP", requires = "robust", conflicts_with_all = ["plant", "spread"])]
    robust_from: Option<String>,
    /// Worker threads (default: one per core); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// `--objective`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ObjectiveArg {
    /// The mean IAE over the plants.
    Mean,
    /// The 90th percentile.
    P90,
    /// The worst plant.
    Worst,
}

impl From<ObjectiveArg> for pma_studies::tune::Aggregate {
    fn from(o: ObjectiveArg) -> Self {
        match o {
            ObjectiveArg::Mean => Self::Mean,
            ObjectiveArg::P90 => Self::P90,
            ObjectiveArg::Worst => Self::Worst,
        }
    }
}

/// Evaluations done by this process's search (one search per process).
static EVALUATED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

impl Args {
    /// The command line that reproduces a tuning (written into the gain file).
    fn command(&self, plant: &str) -> String {
        let budget = self
            .max_variation
            .map_or(String::new(), |v| format!(" --max-variation {v}"));
        let objective = format!("{:?}", self.objective).to_lowercase();
        let robust = match (self.robust, &self.robust_from) {
            (Some(n), Some(sweep)) => {
                format!(" --robust {n} --robust-from {sweep} --objective {objective}")
            }
            (Some(n), None) => format!(
                " --robust {n} --spread {} --objective {objective}",
                self.spread
            ),
            (None, _) => String::new(),
        };
        let plant = if self.robust_from.is_some() {
            String::new()
        } else {
            format!(" --plant {plant}")
        };
        format!(
            "pma-exo tune --controller {}{plant} --population {} --generations {} --duration {} --seed {}{budget}{robust}",
            self.controller, self.population, self.generations, self.duration, self.seed
        )
    }
}

/// Largest firefly population accepted (`tune`, `rig commission`).
const MAX_POPULATION: usize = 10_000;
/// Most generations accepted.
const MAX_GENERATIONS: usize = 100_000;
/// Most plants a robust tuning takes.
const MAX_ROBUST: usize = 1000;
/// Wall time of one control period of a tuning's bench run, per thread (s): an upper
/// bound (a 20 s run takes about 6 ms on this project's 2-core machine, 0.3 us a period).
const TUNING_PERIOD_S: f64 = 1e-6;

/// Checks the search's size and returns its evaluations: the initial population, then one
/// per firefly per generation at most (the tuner's own count is reported after the run).
pub(crate) fn evaluations(population: usize, generations: usize) -> Result<f64> {
    if !(2..=MAX_POPULATION).contains(&population) {
        bail!("--population must be 2 to {MAX_POPULATION} (got {population})");
    }
    if !(1..=MAX_GENERATIONS).contains(&generations) {
        bail!("--generations must be 1 to {MAX_GENERATIONS} (got {generations})");
    }
    let n = generations
        .checked_add(1)
        .and_then(|g| g.checked_mul(population))
        .context("the search is too large to count")?;
    Ok(n as f64)
}

/// Checks `--robust`'s number of plants.
pub(crate) fn check_robust(plants: usize) -> Result<()> {
    if !(1..=MAX_ROBUST).contains(&plants) {
        bail!("--robust must be 1 to {MAX_ROBUST} plants (got {plants})");
    }
    Ok(())
}

/// Refuses a tuning of `evaluations` runs of `duration_s` on each of `plants` estimated
/// over an hour unless `yes`; returns the estimate (s, one thread).
pub(crate) fn check_tuning_wall_time(
    duration_s: f64,
    evaluations: f64,
    plants: usize,
    yes: bool,
) -> Result<f64> {
    let spec = pma_bench::RunSpec {
        duration_s,
        ..Default::default()
    };
    let runs = evaluations * plants as f64;
    let periods = spec.periods()? as f64 * runs;
    output::check_wall_time("this tuning", periods, TUNING_PERIOD_S, yes)?;
    Ok(periods * TUNING_PERIOD_S)
}

/// Runs `tune`.
pub fn run(a: Args) -> Result<i32> {
    check_duration(a.duration)?;
    let evaluations = evaluations(a.population, a.generations)?;
    if let Some(v) = a.max_variation {
        if !(v.is_finite() && v > 0.0) {
            bail!("--max-variation must be a finite number of bar/s > 0 (got {v})");
        }
    }
    let plant = pma_bench::PlantConfig::load(&a.plant)?;
    let plants = match a.robust {
        Some(n) => {
            check_robust(n)?;
            match &a.robust_from {
                Some(sweep) => pma_studies::tune::population_plants(
                    &pma_studies::sweep::load(sweep)?,
                    n,
                    a.seed,
                )?,
                None => pma_studies::tune::robust_plants(&plant, n, a.spread, a.seed)?,
            }
        }
        None => vec![plant.clone()],
    };
    check_tuning_wall_time(a.duration, evaluations, plants.len(), a.yes)?;
    if let (Some(out), Some(plant)) = (&a.out, output::input_file(&a.plant)) {
        output::refuse_input_as_output(&[("plant file", plant)], &[("--out", out)])?;
    }
    let out = a.out.as_deref().map(OutFile::create).transpose()?;
    let opts = pma_studies::tune::FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        progress: Some(&EVALUATED),
        ..Default::default()
    };
    let _bar = output::follow_progress(&EVALUATED, evaluations as u64, "runs");
    let objective = pma_studies::tune::Objective {
        duration_s: a.duration,
        max_variation_pa_per_s: a.max_variation.map(|v| v * 1e5),
        rig: None,
    };
    let stop = output::stop_flag()?;
    let found = super::with_threads(a.threads, || {
        pma_studies::tune::tune_robust(
            a.controller,
            &plants,
            a.objective.into(),
            &opts,
            &objective,
            &[],
            &stop,
        )
    })?;
    if interrupted(&stop, a.out.as_deref()) {
        return Ok(output::INTERRUPTED);
    }
    let Some((res, scores)) = found else {
        bail!(
            "{} has no search space here (pass --gains to change its gains)",
            a.controller
        );
    };
    let (iae, var) = (res.score.iae_m, res.score.variation_pa_per_s / 1e5);
    if a.robust.is_some() {
        let worst = scores.iter().map(|s| s.iae_m).fold(0.0, f64::max);
        eprintln!(
            "robust over {} plants: IAE {:?} {iae:.4e} m, worst {worst:.4e} m",
            scores.len(),
            a.objective
        );
    }
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
    #[arg(long, value_name = ControllerKind::NAMES, default_value = "aprc-ndo")]
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
    /// More scenarios (comma-separated) each gain set also runs on; the objective is the
    /// worst of them all (a robust tuning, e.g. a passive and a spastic patient).
    #[arg(long, value_delimiter = ',')]
    also: Vec<String>,
    /// Optimiser seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the gain file here (created before the search; printed otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Worker threads (default: one per core); the result does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Degrees of objective per bar/s of command variation (0.01: a chattering valve
    /// must not buy tracking accuracy; more for a valve that cannot follow a chatter).
    #[arg(long, default_value_t = pma_studies::leg_tune::VARIATION_WEIGHT_DEG_PER_BAR_S, allow_negative_numbers = true)]
    variation_weight: f64,
    /// Runs of a local polish after the firefly search (a compass search around its best,
    /// in parallel); with it the search also starts from the scenario's own gains (those
    /// its support selects, `control.gains_below_support`; its gain set's,
    /// `control.gain_set`, for a controller other than APRC-NDO) and never
    /// ends worse than them. 0 (default): the plain search the shipped in-air gains
    /// came from.
    #[arg(long, default_value_t = 0)]
    polish: usize,
    /// The share of each muscle's rating its peak force may reach (0-1; 0.9 keeps a
    /// tenth free).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    max_rating: f64,
    // The bound comes from the constant that checks it, so the help cannot fall behind.
    #[arg(long, value_delimiter = ',', help = format!(
        "Physics substeps per control period (comma-separated, each {}): every scenario \
         runs at each, and the objective is the worst, so that the gains found hold at a \
         finer step too (a loop tuned at one step can rely on its integrator's damping). \
         Default: each scenario's own",
        super::physics_substeps_range()
    ))]
    physics_substeps: Vec<u32>,
    /// On a treadmill, a run that does not walk by its verdict (strides, stance RMS within
    /// 2 deg, the belt's load) scores 50 deg more: walking becomes a constraint the
    /// variation weight cannot trade away.
    #[arg(long)]
    require_walking: bool,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

/// The objective's weights from `--variation-weight` and `--max-rating`, checked.
fn leg_objective(a: &LegArgs) -> Result<pma_studies::leg_tune::LegObjective> {
    if !(a.variation_weight.is_finite() && (0.0..=10.0).contains(&a.variation_weight)) {
        bail!(
            "--variation-weight = {} is invalid: must be 0 to 10 deg per bar/s",
            a.variation_weight
        );
    }
    if !(a.max_rating.is_finite() && a.max_rating > 0.0 && a.max_rating <= 1.0) {
        bail!(
            "--max-rating = {} is invalid: must be > 0 and at most 1 (the rating itself)",
            a.max_rating
        );
    }
    Ok(pma_studies::leg_tune::LegObjective {
        variation_weight_deg_per_bar_s: a.variation_weight,
        rating_max: a.max_rating,
        require_walking: a.require_walking,
    })
}

/// The scenario and the `--also` ones, each checked for the run's duration, each at every
/// `--physics-substeps` count, with each run's cost relative to its scenario's own step.
fn tuning_scenarios(a: &LegArgs) -> Result<(Vec<pma_leg::LoadedScenario>, Vec<f64>)> {
    for &n in &a.physics_substeps {
        super::check_physics_substeps(n)?;
    }
    let mut loaded = Vec::with_capacity((1 + a.also.len()) * a.physics_substeps.len().max(1));
    let mut cost = Vec::with_capacity(loaded.capacity());
    for name in std::iter::once(&a.scenario).chain(&a.also) {
        let l = pma_leg::Scenario::load(name)?;
        l.scenario.check_run_duration(a.duration)?;
        if a.physics_substeps.is_empty() {
            loaded.push(l);
            cost.push(1.0);
            continue;
        }
        let own = f64::from(l.scenario.physics_substeps.max(1));
        for &n in &a.physics_substeps {
            let mut at_n = l.clone();
            at_n.scenario.physics_substeps = n;
            loaded.push(at_n);
            // rapier's step dominates a leg's period, so a run costs about its substeps.
            cost.push(f64::from(n) / own);
        }
    }
    pma_studies::leg_tune::common_base(&loaded, a.controller)?;
    Ok((loaded, cost))
}

/// Runs `tune-leg`.
pub fn run_leg(a: LegArgs) -> Result<i32> {
    check_duration(a.duration)?;
    let evaluations = evaluations(a.population, a.generations)?;
    let weigh = leg_objective(&a)?;
    let (scenarios, cost) = tuning_scenarios(&a)?;
    let periods: f64 = scenarios
        .iter()
        .zip(&cost)
        .map(|(l, c)| a.duration / l.scenario.period_s * evaluations * c)
        .sum();
    output::check_wall_time("this tuning", periods, LEG_PERIOD_S, a.yes)?;
    if let Some(out) = &a.out {
        let inputs: Vec<_> = std::iter::once(&a.scenario)
            .chain(&a.also)
            // One loaded scenario per name and substep count: the files are the name's.
            .zip(scenarios.chunks(a.physics_substeps.len().max(1)))
            .flat_map(|(name, l)| super::scenario_inputs(name, &l[0], None))
            .collect();
        output::refuse_input_as_output(&inputs, &[("--out", out)])?;
    }
    let out = a.out.as_deref().map(OutFile::create).transpose()?;
    let opts = pma_studies::tune::FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        progress: Some(&EVALUATED),
        ..Default::default()
    };
    let _bar = output::follow_progress(&EVALUATED, evaluations as u64 + a.polish as u64, "runs");
    let stop = output::stop_flag()?;
    let budget = pma_studies::leg_tune::LegBudget {
        firefly: opts,
        polish_evaluations: a.polish,
        progress: Some(&EVALUATED),
    };
    let found = super::with_threads(a.threads, || {
        pma_studies::leg_tune::tune(&scenarios, a.controller, &budget, a.duration, &weigh, &stop)
    })??;
    if interrupted(&stop, a.out.as_deref()) {
        return Ok(output::INTERRUPTED);
    }
    let Some(t) = found else {
        bail!(
            "{} has no search space here (pass --gains to simulate to change its gains)",
            a.controller
        );
    };
    if t.objective >= pma_studies::leg_tune::FAILED_RUN {
        bail!(
            "every one of the {} runs failed or went non-finite: no gains to report",
            t.evaluations
        );
    }
    if t.objective >= pma_studies::leg_tune::OVER_RATING {
        bail!(
            "every one of the {} runs pulled a muscle past {} of its rating (the best to {:.2} times it): no gains to report",
            t.evaluations,
            a.max_rating,
            a.max_rating + (t.objective - pma_studies::leg_tune::OVER_RATING) / 100.0
        );
    }
    let also = if a.also.is_empty() {
        String::new()
    } else {
        format!(" --also {}", a.also.join(","))
    };
    let mut weights = if weigh == pma_studies::leg_tune::LegObjective::default() {
        String::new()
    } else {
        format!(
            " --variation-weight {} --max-rating {}",
            a.variation_weight, a.max_rating
        )
    };
    if a.polish > 0 {
        weights.push_str(&format!(" --polish {}", a.polish));
    }
    if !a.physics_substeps.is_empty() {
        let list: Vec<String> = a.physics_substeps.iter().map(u32::to_string).collect();
        weights.push_str(&format!(" --physics-substeps {}", list.join(",")));
    }
    if a.require_walking {
        weights.push_str(" --require-walking");
    }
    let mut rating = if a.max_rating < 1.0 {
        format!("within {} of its rating", a.max_rating)
    } else {
        String::from("within its rating")
    };
    if a.require_walking {
        rating.push_str(", every run walking by its verdict (50 more where not)");
    }
    let text = format!(
        "# Tuned by `pma-exo tune-leg {}{also} --controller {} --population {} --generations {} --duration {} --seed {}{weights}`\n# ({} runs, objective {:.4}: {} + {} x bar/s, the worst of the scenarios, every muscle {rating})\n{}",
        a.scenario,
        a.controller,
        a.population,
        a.generations,
        a.duration,
        a.seed,
        t.evaluations,
        t.objective,
        if scenarios.iter().any(|l| l.scenario.treadmill.is_some()) {
            "the worst foot's stance-phase RMS of hip + knee in deg"
        } else {
            "hip RMS + knee RMS in deg"
        },
        a.variation_weight,
        t.config.to_toml_string()
    );
    write_gain_file(out, &text)?;
    eprintln!(
        "{}: objective {:.4} after {} runs (the scenario's own gains: {:.4})",
        a.controller, t.objective, t.evaluations, t.start_objective
    );
    Ok(0)
}

/// Whether a signal stopped the search; says so, and that nothing was written.
fn interrupted(stop: &std::sync::atomic::AtomicBool, out: Option<&std::path::Path>) -> bool {
    let stopped = stop.load(std::sync::atomic::Ordering::Relaxed);
    if stopped {
        match out {
            Some(p) => eprintln!(
                "interrupted: the search was stopped; `{}` was not written (a previous file there is unchanged)",
                p.display()
            ),
            None => eprintln!("interrupted: the search was stopped; no gains to report"),
        }
    }
    stopped
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
