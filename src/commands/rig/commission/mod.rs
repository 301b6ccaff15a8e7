//! `pma-exo rig commission`: excite, identify, tune robustly and verify, in one command.
//!
//! Every argument is checked, and every stage's time estimated, before the muscle first
//! moves. The operator's stop (SIGINT/SIGTERM, the one flag of `output::stop_flag`) ends
//! the command at any stage: the run under way vents, no later stage runs, nothing is kept
//! as tuned gains, the report says at which stage, and the status is 130. A supervisor
//! fault of the controller as configured (stage 1) is a result: recorded, and the
//! commissioning goes on (that controller is what it is there to replace).
mod report;

use super::supervised::{check_rig_wall_time, warn_if_not_vented, with_added_mass};
use crate::commands::tune::{check_robust, check_tuning_wall_time, evaluations};
use crate::output::{self, OutFile};
use anyhow::{bail, Context, Result};
use pma_bench::PlantConfig;
use pma_control::{ControllerConfig, ControllerKind};
use pma_exo::setup::load_id_log as load_log;
use pma_rig::{RigConfig, RunOptions};
use pma_studies::identify::{identify_logs, IdLog, Identified, MIN_LOG_S};
use pma_studies::tune::{
    robust_plants, tune_robust_around, Aggregate, FireflyOptions, Objective, RigScenario,
    TuneResult,
};
use report::{Report, RunResult};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// `rig commission`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Rig configuration: `virtual` (default), `pci6052e`, or a .toml file.
    #[arg(long, default_value = "virtual")]
    config: String,
    /// A new directory for the logs, plant.toml, gains.toml, report.md.
    #[arg(long)]
    out: PathBuf,
    /// The load the muscle lifts, weighed (kg); default the configuration's `[load]
    /// mass_kg`.
    #[arg(long, allow_negative_numbers = true)]
    load_kg: Option<f64>,
    /// When the load is not weighed: a second excitation with this known mass added (kg)
    /// identifies it (a real rig asks you to hang it).
    #[arg(long, allow_negative_numbers = true, conflicts_with = "load_kg")]
    added_mass_kg: Option<f64>,
    /// The controller to commission (default: the configuration's).
    #[arg(long, value_name = ControllerKind::NAMES)]
    controller: Option<ControllerKind>,
    /// Seconds of excitation (at least 10, what identification needs).
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    excite_duration: f64,
    /// Plants of the robust tuning.
    #[arg(long, default_value_t = 8)]
    robust: usize,
    /// Their spread around the identified plant (0..=0.5).
    #[arg(long, default_value_t = 0.1, allow_negative_numbers = true)]
    spread: f64,
    /// Budget on the command's activity in the tuning (bar/s).
    #[arg(long, default_value_t = 12.0, allow_negative_numbers = true)]
    max_variation: f64,
    /// Fireflies of the tuning.
    #[arg(long, default_value_t = 20)]
    population: usize,
    /// Generations of the tuning.
    #[arg(long, default_value_t = 40)]
    generations: usize,
    /// The lowest held-out fit (%) of the identified model the tuning starts from, as
    /// `identify --min-fit`.
    #[arg(long, default_value_t = crate::commands::identify::MIN_FIT_PERCENT, allow_negative_numbers = true)]
    min_fit: f64,
    /// Seed of the tuning and the bootstrap.
    #[arg(long, default_value_t = 2019)]
    seed: u64,
    /// Do not ask before the stages that move the muscle (a real board asks), and run a
    /// commissioning estimated over an hour.
    #[arg(long)]
    yes: bool,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

/// Seconds of bench simulation per gain set and plant in the tuning (the paper's sine).
const TUNING_RUN_S: f64 = 20.0;

/// The tuning's generations split into this many searches from fresh populations, each
/// keeping the best so far ([`pma_studies::tune::firefly_restarts`]).
const RESTARTS: usize = 1;

/// Evaluations of the compass search that polishes the tuning's best (each over every
/// robust plant): two of the firefly search's generations of 20.
const POLISH_EVALUATIONS: usize = 40;

/// Wall time of identification per logged period (s): an upper bound on what
/// docs/commissioning.md measured (7-16 s for a 60 s log with a weighed load, 36-44 s for
/// the added mass's two; at most 0.37 ms a period).
const IDENTIFY_PERIOD_S: f64 = 4e-4;

/// The operator stopped the commissioning (SIGINT/SIGTERM) during `stage`.
#[derive(Debug, thiserror::Error)]
#[error("interrupted at stage {stage} by the operator")]
struct Interrupted {
    stage: u32,
}

/// What the checks before stage 1 settle: nothing of it moves the muscle or writes.
struct Plan {
    cfg: RigConfig,
    /// The configuration's directory (its gain file is relative to it).
    dir: PathBuf,
    /// A real board: ask before each stage that moves the muscle.
    real: bool,
    load: Load,
    kind: ControllerKind,
    /// The gains of the "before" run, and of the first verification.
    current: ControllerConfig,
    /// Where they come from, in words.
    gain_source: String,
    /// The tuning's estimated wall time on one thread (s).
    tuning_s: f64,
}

impl Plan {
    /// Checks every argument and estimates every stage before anything moves or is written.
    fn check(a: &Args) -> Result<Self> {
        let (cfg, dir) = RigConfig::load(&a.config)?;
        if a.out.exists() {
            bail!(
                "`{}` exists: commissioning writes into a new directory (nothing is overwritten)",
                a.out.display()
            );
        }
        if !(a.excite_duration.is_finite() && a.excite_duration >= MIN_LOG_S) {
            bail!(
                "--excite-duration must be a finite number of seconds >= {MIN_LOG_S}, what identification needs (got {})",
                a.excite_duration
            );
        }
        cfg.default_excitation(a.excite_duration)
            .validate()
            .context("--excite-duration")?;
        if !(a.max_variation.is_finite() && a.max_variation > 0.0) {
            bail!(
                "--max-variation must be a finite number of bar/s > 0 (got {})",
                a.max_variation
            );
        }
        crate::commands::identify::check_min_fit(a.min_fit)?;
        check_robust(a.robust)?;
        pma_studies::tune::check_spread(a.spread).map_err(|e| pma_model::Invalid {
            name: "--spread".into(),
            ..e
        })?;
        let tuning_runs = evaluations(a.population, a.generations)?
            + ((RESTARTS - 1) * a.population + POLISH_EVALUATIONS) as f64;
        let load = Load::of(a, &cfg)?;
        let excitations = match load {
            Load::Weighed(_) => 1.0,
            Load::Added(..) => 2.0,
        };
        // The rig's runs: before, the excitation(s), the two verifications.
        check_rig_wall_time(
            &cfg,
            cfg.duration_s * 3.0 + excitations * a.excite_duration,
            false,
            a.yes,
        )?;
        output::check_wall_time(
            "this identification",
            excitations * a.excite_duration / cfg.period_s,
            IDENTIFY_PERIOD_S,
            a.yes,
        )?;
        // Each search runs on the identified plant alone (once per share of the budget),
        // then on it and the drawn plants.
        let centred = pma_studies::tune::CENTRED_BUDGET_SHARES.len();
        let searches = pma_studies::tune::ROBUST_SEARCHES;
        let plant_runs = searches * (a.robust + 1 + centred);
        let tuning_s = check_tuning_wall_time(TUNING_RUN_S, tuning_runs, plant_runs, a.yes)?;
        let configured = cfg.control_kind()?;
        let kind = a.controller.unwrap_or(configured);
        if kind.search_space().is_empty() {
            bail!("{kind} has no gains to tune: pass another --controller");
        }
        // Another controller than the configured one starts from its defaults.
        let (current, gain_source) = if kind == configured {
            let source = match &cfg.control.gains {
                Some(path) => format!("the gains of `{}`", dir.join(path).display()),
                None => default_gains(kind),
            };
            (cfg.control.controller_config(kind, &dir)?, source)
        } else {
            (
                kind.default_config(),
                format!(
                    "{} (--controller; the configuration's is {configured})",
                    default_gains(kind)
                ),
            )
        };
        Ok(Self {
            real: cfg.virtual_rig.is_none(),
            cfg,
            dir,
            load,
            kind,
            current,
            gain_source,
            tuning_s,
        })
    }
}

/// What fixes the load's mass for identification.
enum Load {
    /// Weighed (kg): `--load-kg`, or the configuration's `[load] mass_kg`.
    Weighed(f64),
    /// Not weighed: a second excitation with this mass (kg) added, on this configuration.
    Added(f64, Box<RigConfig>),
}

impl Load {
    fn of(a: &Args, cfg: &RigConfig) -> Result<Self> {
        if let Some(m) = a.load_kg {
            pma_model::error::within(
                "--load-kg",
                m,
                0.05,
                pma_model::MAX_LOAD_KG,
                "must be 0.05 to 600 kg",
            )?;
        }
        match (a.load_kg.or(cfg.load.mass_kg), a.added_mass_kg) {
            (None, None) => bail!(
                "the load is not known: pass --load-kg (weighed), set [load] mass_kg in the rig configuration, or pass --added-mass-kg M for a second excitation with M kg added"
            ),
            (Some(_), Some(_)) => bail!(
                "--added-mass-kg is for an unweighed load; the configuration's [load] mass_kg is set"
            ),
            (Some(m), None) => Ok(Self::Weighed(m)),
            (None, Some(m)) => {
                // A mass the data can see: 0 kg would repeat the first excitation.
                pma_model::error::within(
                    "--added-mass-kg",
                    m,
                    0.05,
                    pma_model::MAX_LOAD_KG,
                    "must be 0.05 to 600 kg (a known mass hung on the load)",
                )?;
                Ok(Self::Added(m, Box::new(with_added_mass(cfg.clone(), m)?)))
            }
        }
    }
}

/// The gains a controller has without a gain file.
fn default_gains(kind: ControllerKind) -> String {
    if kind == ControllerKind::AprcNdo {
        "the paper's gains (its defaults)".into()
    } else {
        "its default gains".into()
    }
}

/// The commissioning's directory: created when the first file is about to be written, and
/// removed at the end if nothing is in it (a confirmation refused, a board that cannot be
/// opened), so that the same command can run again.
struct OutDir {
    path: PathBuf,
    created: bool,
}

impl OutDir {
    fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            created: false,
        }
    }

    /// `name` inside the directory, created if it is not yet.
    fn file(&mut self, name: &str) -> Result<PathBuf> {
        if !self.created {
            std::fs::create_dir(&self.path)
                .with_context(|| format!("cannot create `{}`", self.path.display()))?;
            self.created = true;
        }
        Ok(self.path.join(name))
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if self.created {
            // Fails, as it should, on a directory that holds anything.
            let _ = std::fs::remove_dir(&self.path);
        }
    }
}

/// Runs `rig commission`.
pub fn run(a: Args) -> Result<i32> {
    let plan = Plan::check(&a)?;
    let stop = output::stop_flag()?;
    let mut out = OutDir::new(&a.out);
    let mut report = Report::new(&a, &plan);
    match commission(&a, &plan, &stop, &mut out, &mut report) {
        Ok(()) => Ok(0),
        Err(e) => match e.downcast_ref::<Interrupted>() {
            Some(&Interrupted { stage }) => {
                eprintln!(
                    "interrupted at stage {stage} by the operator: the valve vented, no later stage ran, no gains kept"
                );
                report.interrupted(stage, &a, out.created.then_some(out.path.as_path()))?;
                Ok(output::INTERRUPTED)
            }
            None => Err(e),
        },
    }
}

/// Prints a stage's heading.
fn stage(n: u32, what: &str) {
    eprintln!("[{n}/5] {what}");
}

/// The stages, recorded into `report` as they run.
fn commission(
    a: &Args,
    plan: &Plan,
    stop: &AtomicBool,
    out: &mut OutDir,
    report: &mut Report,
) -> Result<()> {
    run_before(a, plan, stop, out, report)?;

    stage(2, "excitation");
    let logs = excite(a, plan, stop, out)?;

    stage(3, "identification");
    let id = identify(&logs, plan, a, stop, out)?;
    let plant = id.plant_config(&logs[0]);
    OutFile::create(&out.file("plant.toml")?)?
        .finish_with(&toml::to_string(&plant).context("cannot serialise the plant")?)?;
    report.plant = Some(out.path.join("plant.toml"));
    report.identified = Some(id);

    let tuned = tune(a, plan, &plant, stop, report)?;
    let verified = verify(a, plan, &plant, tuned.as_ref(), stop, out, report)?;
    keep(a, plan, tuned.as_ref(), &verified, &logs[0], out, report)
}

/// Stage 1: the current controller as configured, a result even if the supervisor stops it.
fn run_before(
    a: &Args,
    plan: &Plan,
    stop: &AtomicBool,
    out: &mut OutDir,
    report: &mut Report,
) -> Result<()> {
    let cfg = &plan.cfg;
    stage(1, "the current controller, as configured");
    confirm("the run before", 1, plan, a.yes, stop)?;
    let before = RunOptions {
        controller: Some(plan.current),
        log_path: Some(out.file("before.csv")?),
        ..RunOptions::default()
    };
    let what = format!(
        "{}, {}, the configuration's nominal",
        plan.kind, plan.gain_source
    );
    let result = rig_run(cfg, &plan.dir, &before, stop, 1, what)?;
    if let Some(f) = &result.fault {
        eprintln!(
            "the run before was stopped by the supervisor at {:.1} s: {f} (vented); a result: the commissioning goes on",
            result.faulted_at_s.unwrap_or(0.0)
        );
    }
    report.before = Some(result);

    Ok(())
}

/// Stage 4: the robust tuning on the identified plant and plants around it (tuned on the
/// identified one first, [`tune_robust_around`]); the tuned gains if they kept within the
/// command's variation budget on every one.
fn tune(
    a: &Args,
    plan: &Plan,
    plant: &PlantConfig,
    stop: &AtomicBool,
    report: &mut Report,
) -> Result<Option<TuneResult>> {
    let cfg = &plan.cfg;
    stage(
        4,
        &format!(
            "robust tuning of {} on the identified plant, then on it and {} plants around it (at most about {:.0} s on this machine's cores)",
            plan.kind,
            a.robust,
            plan.tuning_s / rayon::current_num_threads() as f64
        ),
    );
    let plants = robust_plants(plant, a.robust, a.spread, a.seed)?;
    // The gains are scored on the run the rig will make: its reference entered from the
    // vented rest, inside its position window.
    let reference = cfg.reference(0.0);
    let objective = Objective {
        duration_s: TUNING_RUN_S,
        max_variation_pa_per_s: Some(a.max_variation * 1e5),
        rig: Some(RigScenario {
            trajectory: reference.trajectory,
            ramp_s: reference.ramp_s,
            position_min_m: cfg.limits.position_min_m,
            position_max_m: cfg.limits.position_max_m,
        }),
    };
    let opts = FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        polish: POLISH_EVALUATIONS,
        restarts: RESTARTS,
        ..FireflyOptions::default()
    };
    // The search starts fireflies from the gains that run now and from the shipped sets
    // (the bench's tuned ones, those tuned within small activity budgets): it keeps the
    // best of them unless it finds better on the plants around the identified one, then
    // polishes its best. The identified plant is tuned on alone first, within the whole
    // budget and within 0.8 and 0.6 of it: those sets start the robust search, which
    // otherwise settled on detuned sets for 2-3 seeds in 10; the best of three such
    // searches is kept.
    let mut starts = vec![plan.current];
    starts.extend(pma_studies::tune::shipped_starts(plan.kind));
    let tuned = tune_robust_around(
        plan.kind,
        (plant, &plants),
        Aggregate::Mean,
        &opts,
        &objective,
        &starts,
        stop,
    );
    if stop.load(Ordering::Relaxed) {
        return Err(Interrupted { stage: 4 }.into());
    }
    report.tuning = tuned.as_ref().map(|(r, _)| report::Tuning {
        runs: r.evaluations,
        iae_m: r.score.iae_m,
        variation_bar_per_s: r.score.variation_pa_per_s / 1e5,
        within_budget: r.feasible,
    });

    Ok(tuned.map(|(r, _)| r).filter(|r| r.feasible))
}

/// Stage 5's two runs: the current gains and the tuned ones (if any), each on the rig told
/// the identified plant.
struct Verified {
    current: RunResult,
    tuned: Option<RunResult>,
}

/// Stage 5: the verification with the identified plant told.
fn verify(
    a: &Args,
    plan: &Plan,
    plant: &PlantConfig,
    tuned: Option<&TuneResult>,
    stop: &AtomicBool,
    out: &mut OutDir,
    report: &mut Report,
) -> Result<Verified> {
    let cfg = &plan.cfg;
    stage(5, "verification with the identified plant told");
    let mut told = cfg.clone();
    told.control.nominal = plant.nominal;
    confirm("the verification", 5, plan, a.yes, stop)?;
    // A gain set the supervisor stops (the muscle out of its window, say) is a result:
    // it is not kept, and the other is verified all the same. The operator's stop is not:
    // it ends the commissioning there.
    let mut verify = |gains: ControllerConfig, log: &str, what: String| -> Result<RunResult> {
        let o = RunOptions {
            controller: Some(gains),
            log_path: Some(out.file(log)?),
            ..RunOptions::default()
        };
        let r = rig_run(&told, &plan.dir, &o, stop, 5, what)?;
        if let Some(f) = &r.fault {
            eprintln!("the verification with {log} was stopped by the supervisor: {f}");
        }
        Ok(r)
    };
    let current = verify(
        plan.current,
        "after-current-gains.csv",
        format!(
            "{}, {}, the identified plant told",
            plan.kind, plan.gain_source
        ),
    )?;
    report.told = Some(current.clone());
    let tuned_run = match tuned {
        Some(t) => Some(verify(
            t.config,
            "after-tuned-gains.csv",
            format!(
                "{}, robustly tuned on the identified plant and {} plants within {} % of it, the identified plant told",
                plan.kind,
                a.robust,
                a.spread * 100.0
            ),
        )?),
        None => None,
    };
    report.tuned = tuned_run.clone();
    Ok(Verified {
        current,
        tuned: tuned_run,
    })
}

/// Keeps the gains the rig says track best (the tuned ones only if they completed and beat
/// the current ones; the current ones only if they completed), or fails saying why.
fn keep(
    a: &Args,
    plan: &Plan,
    tuned: Option<&TuneResult>,
    verified: &Verified,
    log: &IdLog,
    out: &mut OutDir,
    report: &mut Report,
) -> Result<()> {
    let (current, tuned_run) = (&verified.current, &verified.tuned);
    // The tuned gains are kept only if they completed and the rig says they track better
    // than the current ones (up to their fault, if the supervisor stopped them); the
    // current ones only if they completed.
    let tuned_better = tuned_run
        .as_ref()
        .is_some_and(|r| r.fault.is_none() && r.rte_percent < current.rte_percent);
    let (kept, gains, rte_after) = match tuned {
        Some(t) if tuned_better => ("tuned", t.config, report_rte(tuned_run)),
        _ if current.fault.is_none() => ("current", plan.current, current.rte_percent),
        _ => {
            report.finish(a, &out.path, log, tuned.is_some())?;
            bail!(
                "no gain set to keep: the current gains faulted in the verification and no tuned gains did better; the rig keeps its configuration (see {})",
                out.path.join("report.md").display()
            );
        }
    };
    OutFile::create(&out.file("gains.toml")?)?.finish_with(&format!(
        "# `pma-exo rig commission` ({kept} gains; RTE {rte_after:.3} % on the rig told the identified plant)\n{}",
        gains.to_toml_string()
    ))?;
    report.kept = Some(kept);
    report.rte_after_percent = Some(rte_after);
    report.gains = Some(out.path.join("gains.toml"));
    report.finish(a, &out.path, log, tuned.is_some())
}

/// The RTE of a verification that ran.
fn report_rte(run: &Option<RunResult>) -> f64 {
    run.as_ref().map_or(f64::NAN, |r| r.rte_percent)
}

/// Stage 2: the excitation (and the second, with the added mass); their logs.
fn excite(a: &Args, plan: &Plan, stop: &AtomicBool, out: &mut OutDir) -> Result<Vec<IdLog>> {
    confirm("the excitation", 2, plan, a.yes, stop)?;
    let options = RunOptions {
        duration_s: Some(a.excite_duration),
        log_path: Some(out.file("excite.csv")?),
        excitation: Some(plan.cfg.default_excitation(a.excite_duration)),
        ..RunOptions::default()
    };
    let what = "the excitation".to_owned();
    complete(rig_run(&plan.cfg, &plan.dir, &options, stop, 2, what)?)?;
    let mut logs = vec![load_log(&out.path.join("excite.csv"), false)?];
    if let Load::Added(m, cfg_added) = &plan.load {
        confirm(
            &format!("the excitation with {m} kg more on the load (hang it now)"),
            2,
            plan,
            a.yes,
            stop,
        )?;
        let o = RunOptions {
            log_path: Some(out.file("excite-added-mass.csv")?),
            ..options
        };
        let what = "the excitation with the added mass".to_owned();
        complete(rig_run(cfg_added, &plan.dir, &o, stop, 2, what)?)?;
        logs.push(load_log(&out.path.join("excite-added-mass.csv"), false)?);
    }
    Ok(logs)
}

/// An excitation the supervisor stopped cannot be identified from: the end, named.
fn complete(r: RunResult) -> Result<()> {
    match &r.fault {
        Some(f) => bail!(
            "{} was stopped by the supervisor at {:.1} s: {f} (vented; log {})",
            r.what,
            r.faulted_at_s.unwrap_or(0.0),
            r.log
        ),
        None => Ok(()),
    }
}

/// Stage 3: the identification, refused below `--min-fit`.
fn identify(
    logs: &[IdLog],
    plan: &Plan,
    a: &Args,
    stop: &AtomicBool,
    out: &OutDir,
) -> Result<Identified> {
    let weighed_kg = match plan.load {
        Load::Weighed(m) => Some(m),
        Load::Added(..) => None,
    };
    let id = match identify_logs(logs, weighed_kg, a.seed, stop) {
        Err(pma_studies::StudyError::Interrupted) => return Err(Interrupted { stage: 3 }.into()),
        r => r?,
    };
    if id.fit_percent < a.min_fit {
        bail!(
            "the identified model fits the held-out quarter at {:.1} % only: stopping before tuning (see {})",
            id.fit_percent,
            out.path.join("excite.csv").display()
        );
    }
    Ok(id)
}

/// Asks on the terminal before a stage that moves a real muscle; the operator's stop
/// while the question waits ends the commissioning at `stage`.
fn confirm(what: &str, stage: u32, plan: &Plan, yes: bool, stop: &AtomicBool) -> Result<()> {
    if stop.load(Ordering::Relaxed) {
        return Err(Interrupted { stage }.into());
    }
    if !plan.real || yes {
        return Ok(());
    }
    let question = format!("{what}: the muscle will move. Air on, area clear?");
    match answered_yes_unless_stopped(&question, stop)? {
        None => Err(Interrupted { stage }.into()),
        Some(true) => Ok(()),
        Some(false) => bail!("commissioning stopped before `{what}`: not confirmed"),
    }
}

/// [`crate::commands::answered_yes`] that gives up (`None`) when `stop` is raised: a signal
/// does not interrupt a read from the terminal, so the answer is read on its own thread.
fn answered_yes_unless_stopped(question: &str, stop: &AtomicBool) -> Result<Option<bool>> {
    let (tx, rx) = std::sync::mpsc::channel();
    let question = question.to_owned();
    std::thread::spawn(move || {
        let _ = tx.send(crate::commands::answered_yes(&question));
    });
    loop {
        match rx.recv_timeout(std::time::Duration::from_millis(50)) {
            Ok(answer) => return answer.map(Some),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) if stop.load(Ordering::Relaxed) => {
                return Ok(None)
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                bail!("cannot read the answer")
            }
        }
    }
}

/// One supervised rig run of `stage`: how it ended, or [`Interrupted`] if the operator
/// stopped it (it vented) or had stopped the commissioning before it started.
fn rig_run(
    cfg: &RigConfig,
    dir: &Path,
    options: &RunOptions,
    stop: &AtomicBool,
    stage: u32,
    what: String,
) -> Result<RunResult> {
    if stop.load(Ordering::Relaxed) {
        return Err(Interrupted { stage }.into());
    }
    let r = pma_rig::run::run(cfg, dir, options, stop, ())?;
    warn_if_not_vented(&r);
    if r.fault.as_deref() == Some("interrupted") || stop.load(Ordering::Relaxed) {
        return Err(Interrupted { stage }.into());
    }
    let faulted_at_s = r.fault.as_ref().map(|_| r.periods as f64 * cfg.period_s);
    Ok(RunResult {
        what,
        log: r.log,
        rte_percent: r.rte_percent,
        fault: r.fault,
        fault_detail: r.fault_detail,
        faulted_at_s,
    })
}
