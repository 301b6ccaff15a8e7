//! `pma-exo`: single-muscle runs, the paper's experiments, and gain tuning.
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use pma_control::{ChirpReference, ControllerConfig, ControllerKind, Reference, SineReference};
use pma_sim::{run_single, PlantConfig, RunSpec, Sample, Samples};
use std::io::Write;
use std::path::{Path, PathBuf};

mod paper;
mod plot;
mod rig;
mod simulate;
use pma_exo::viz;

#[derive(Parser)]
#[command(
    name = "pma-exo",
    version,
    about = "Pneumatic-muscle control (APRC-NDO, Cao et al. 2020): simulation and experiments"
)]
struct Cli {
    /// Without a subcommand: `simulate` (the default gait-training simulation).
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Clone, Copy, ValueEnum)]
enum RefName {
    /// A = 15 mm, f = 0.25 Hz, B = 15 mm.
    Sine,
    /// 0.1 -> 0.5 Hz linearly in 20 s, A = B = 15 mm.
    Chirp,
}

/// Where a run's state goes in Rerun (shared by every command that runs a control loop).
#[derive(clap::Args)]
pub(crate) struct RerunArgs {
    /// Rerun: off, spawn, connect, connect=URL or save=PATH.rrd.
    #[arg(long = "rerun", default_value = "off")]
    pub(crate) sink: pma_viz::Sink,
    /// Log to Rerun at this rate (Hz) instead of every control period.
    #[arg(long)]
    pub(crate) rerun_hz: Option<f64>,
}

#[derive(Subcommand)]
enum Command {
    /// Gait training on the exoskeleton leg (rapier), four muscles under APRC-NDO.
    Simulate {
        /// gait_training (default), gait_realistic, or a scenario .toml file.
        #[arg(default_value = "gait_training")]
        scenario: String,
        /// Simulated seconds (default: the scenario's).
        #[arg(long, allow_negative_numbers = true)]
        duration: Option<f64>,
        /// Write the time series as CSV.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        rerun: RerunArgs,
    },
    /// One controller on the single-muscle bench.
    Single {
        /// aprc-ndo, aprc, psmc, ndo-smc, sta or pid.
        #[arg(long, default_value = "aprc-ndo")]
        controller: ControllerKind,
        /// Reference trajectory.
        #[arg(long, value_enum, default_value = "sine")]
        reference: RefName,
        /// Plant preset (ideal, mismatch, realistic, realistic_known_lag) or a plant .toml file.
        #[arg(long, default_value = "ideal")]
        plant: String,
        /// Simulated seconds.
        #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
        duration: f64,
        /// Gain file (TOML) for the controller.
        #[arg(long)]
        gains: Option<PathBuf>,
        /// Write the time series as CSV.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Print one JSON object instead of a summary line.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        rerun: RerunArgs,
    },
    /// Rerun the paper's experiments in simulation: results.json, report.md, plots.
    Paper {
        /// Output directory.
        #[arg(long, default_value = "paper-out")]
        out: PathBuf,
    },
    /// Tune a leg scenario's shared APRC-NDO gains with the same firefly search (objective:
    /// hip + knee RMS error plus 0.01 deg per bar/s of command variation).
    TuneLeg {
        /// gait_training, gait_realistic, or a scenario .toml file.
        #[arg(default_value = "gait_training")]
        scenario: String,
        /// Fireflies.
        #[arg(long, default_value_t = 20)]
        population: usize,
        /// Generations.
        #[arg(long, default_value_t = 25)]
        generations: usize,
        /// Simulated seconds per evaluation.
        #[arg(long, default_value_t = 6.4)]
        duration: f64,
        /// Optimiser seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The hardware backend: one muscle on a DAQ rig (or the virtual rig).
    Rig {
        #[command(subcommand)]
        command: rig::RigCommand,
    },
    /// Tune a baseline's gains with the firefly algorithm on the sine (IAE objective).
    Tune {
        /// psmc, ndo-smc, sta or pid.
        #[arg(long)]
        controller: ControllerKind,
        /// Plant the gains are tuned on.
        #[arg(long, default_value = "mismatch")]
        plant: String,
        /// Fireflies.
        #[arg(long, default_value_t = 20)]
        population: usize,
        /// Generations.
        #[arg(long, default_value_t = 40)]
        generations: usize,
        /// Simulated seconds per evaluation.
        #[arg(long, default_value_t = 20.0)]
        duration: f64,
        /// Optimiser seed.
        #[arg(long, default_value_t = 2019)]
        seed: u64,
        /// Budget on command activity: mean |du/dt| of the pressure command (bar/s).
        #[arg(long, value_name = "BAR_PER_S", allow_negative_numbers = true)]
        max_variation: Option<f64>,
        /// Write the gain file here (printed otherwise).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                let _ = e.print();
                std::process::exit(0);
            }
            let text = e.to_string();
            eprintln!(
                "{}",
                text.lines().next().unwrap_or("error: invalid arguments")
            );
            std::process::exit(2);
        }
    };
    match run(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            // One line: the error and its causes.
            let chain: Vec<String> = e.chain().map(|c| c.to_string()).collect();
            let line = chain.join(": ");
            eprintln!(
                "error: {}",
                line.split_whitespace().collect::<Vec<_>>().join(" ")
            );
            std::process::exit(1);
        }
    }
}

fn run(cli: Cli) -> Result<i32> {
    let command = cli.command.unwrap_or(Command::Simulate {
        scenario: "gait_training".into(),
        duration: None,
        csv: None,
        json: false,
        rerun: RerunArgs {
            sink: pma_viz::Sink::Off,
            rerun_hz: None,
        },
    });
    match command {
        Command::Rig { command } => rig::run(command),
        other => run_command(other).map(|()| 0),
    }
}

fn run_command(command: Command) -> Result<()> {
    match command {
        Command::Rig { command } => rig::run(command).map(|_| ()),
        Command::Simulate {
            scenario,
            duration,
            csv,
            json,
            rerun,
        } => simulate::run(
            &scenario,
            duration,
            csv.as_deref(),
            json,
            &rerun.sink,
            rerun.rerun_hz,
        ),
        Command::Single {
            controller,
            reference,
            plant,
            duration,
            gains,
            csv,
            json,
            rerun,
        } => single(
            controller,
            reference,
            &plant,
            duration,
            gains.as_deref(),
            csv.as_deref(),
            json,
            (&rerun.sink, rerun.rerun_hz),
        ),
        Command::Paper { out } => paper::run(&out),
        Command::TuneLeg {
            scenario,
            population,
            generations,
            duration,
            seed,
        } => tune_leg(&scenario, population, generations, duration, seed),
        Command::Tune {
            controller,
            plant,
            population,
            generations,
            duration,
            seed,
            max_variation,
            out,
        } => tune(
            controller,
            &plant,
            &TuneSearch {
                population,
                generations,
                duration,
                seed,
                max_variation,
            },
            out.as_deref(),
        ),
    }
}

/// A preset name or a path to a plant TOML file.
pub(crate) fn load_plant(name: &str) -> Result<PlantConfig> {
    Ok(PlantConfig::load(name)?)
}

pub(crate) fn load_gains(kind: ControllerKind, path: Option<&Path>) -> Result<ControllerConfig> {
    let Some(path) = path else {
        return Ok(kind.default_config());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read gain file `{}`", path.display()))?;
    let cfg = ControllerConfig::from_toml_str(&text)
        .with_context(|| format!("gain file `{}`", path.display()))?;
    // APRC and APRC-NDO share one gain set, so an APRC-NDO file may drive the ablation.
    let compatible = cfg.kind() == kind
        || matches!(
            (cfg.kind(), kind),
            (ControllerKind::AprcNdo, ControllerKind::Aprc)
                | (ControllerKind::Aprc, ControllerKind::AprcNdo)
        );
    if !compatible {
        return Err(pma_control::ConfigError::WrongController {
            requested: kind,
            found: cfg.kind(),
        })
        .with_context(|| format!("gain file `{}`", path.display()));
    }
    Ok(match (cfg, kind) {
        (ControllerConfig::AprcNdo(g), ControllerKind::Aprc) => ControllerConfig::Aprc(g),
        (ControllerConfig::Aprc(g), ControllerKind::AprcNdo) => ControllerConfig::AprcNdo(g),
        (c, _) => c,
    })
}

fn check_duration(duration: f64) -> Result<()> {
    if !(duration.is_finite() && duration > 0.0) {
        bail!("--duration must be a finite number of seconds > 0 (got {duration})");
    }
    Ok(())
}

fn reference_of(name: RefName) -> (&'static str, Box<dyn Reference>) {
    match name {
        RefName::Sine => ("sine", Box::new(SineReference::paper())),
        RefName::Chirp => ("chirp", Box::new(ChirpReference::paper())),
    }
}

#[allow(clippy::too_many_arguments)]
fn single(
    kind: ControllerKind,
    reference: RefName,
    plant: &str,
    duration: f64,
    gains: Option<&Path>,
    csv: Option<&Path>,
    json: bool,
    (sink, rerun_hz): (&pma_viz::Sink, Option<f64>),
) -> Result<()> {
    check_duration(duration)?;
    let plant_cfg = load_plant(plant)?;
    let config = load_gains(kind, gains)?;
    let (ref_name, r) = reference_of(reference);
    let spec = RunSpec {
        duration_s: duration,
        ..RunSpec::default()
    };
    let mut viz = viz::open(sink, "pma-exo single", spec.period_s, rerun_hz)?;
    if let Some(v) = viz.as_mut() {
        let meta = format!(
            "# single muscle\n\ncontroller `{kind}`, reference `{ref_name}`, plant `{}`\n\n```toml\n{}```\n",
            plant_cfg.name,
            config.to_toml_string()
        );
        viz::bench_layout(v, &meta)?;
    }
    let mut samples: Vec<Sample> = Vec::with_capacity(if csv.is_some() { spec.steps() } else { 0 });
    let (mut step, mut scalars, mut viz_error) = (0i64, [0.0; 11], None);
    let record = |s: &Sample| {
        step += 1;
        if csv.is_some() {
            samples.push(*s);
        }
        if let Some(v) = viz.as_mut() {
            viz::bench_scalars(s, &mut scalars);
            let frame = pma_viz::Frame {
                t_s: s.t_s,
                step,
                scalars: &scalars,
                link_poses: &[],
                muscle_lines: &[],
            };
            if let Err(e) = v.push(&frame) {
                viz_error.get_or_insert(e);
            }
        }
    };
    let res = run_single(&config, &plant_cfg, r.as_ref(), &spec, &mut Samples(record))?;
    if let Some(e) = viz_error {
        return Err(e.into());
    }
    pma_exo::viz::finish(viz)?;
    if let Some(path) = csv {
        write_csv(path, &samples)?;
    }
    if !res.finite {
        bail!(
            "the run went non-finite (controller {}, plant {})",
            kind,
            plant_cfg.name
        );
    }
    let s = res.stats;
    if json {
        let v = serde_json::json!({
            "controller": kind.as_str(),
            "reference": ref_name,
            "plant": plant_cfg.name,
            "duration_s": duration,
            "mae_m": s.mae_m,
            "iae_m": s.iae_m,
            "rte_percent": s.rte_percent,
            "rms_m": s.rms_m,
            "x_a_m": res.x_a_m,
            "command_variation_bar_per_s": res.command_variation_pa_per_s / 1e5,
            "samples": s.samples,
            "real_time_factor": res.real_time_factor,
        });
        println!("{v}");
    } else {
        println!(
            "{kind} on {} ({ref_name}, {duration} s): MAE {:.3e} m, IAE {:.3e} m, RTE {:.3} %, RMS {:.3e} m, {:.0}x real time",
            plant_cfg.name, s.mae_m, s.iae_m, s.rte_percent, s.rms_m, res.real_time_factor
        );
    }
    Ok(())
}

fn write_csv(path: &Path, samples: &[Sample]) -> Result<()> {
    let file = std::fs::File::create(path)
        .with_context(|| format!("cannot create `{}`", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "t_s,reference_m,position_m,pressure_cmd_pa,pressure_pa,proxy_m,s_p,s_q,gain_hat,disturbance_hat")?;
    for s in samples {
        let d = &s.diagnostics;
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{}",
            s.t_s,
            s.reference_m,
            s.position_m,
            s.pressure_cmd_pa,
            s.pressure_pa,
            d.proxy_position_m,
            d.s_p,
            d.s_q,
            d.gain_hat,
            d.disturbance_hat
        )?;
    }
    w.flush()
        .with_context(|| format!("cannot write `{}`", path.display()))?;
    Ok(())
}

#[allow(clippy::too_many_arguments)]
/// `tune`'s search settings, as given on the command line.
struct TuneSearch {
    population: usize,
    generations: usize,
    duration: f64,
    seed: u64,
    max_variation: Option<f64>,
}

impl TuneSearch {
    /// The command line that reproduces a tuning (written into the gain file).
    fn command(&self, kind: ControllerKind, plant: &str) -> String {
        let budget = self
            .max_variation
            .map_or(String::new(), |v| format!(" --max-variation {v}"));
        format!(
            "pma-exo tune --controller {kind} --plant {plant} --population {} --generations {} --duration {} --seed {}{budget}",
            self.population, self.generations, self.duration, self.seed
        )
    }
}

fn tune(kind: ControllerKind, plant: &str, search: &TuneSearch, out: Option<&Path>) -> Result<()> {
    check_duration(search.duration)?;
    if search.population < 2 {
        bail!(
            "--population must be at least 2 (got {})",
            search.population
        );
    }
    if let Some(v) = search.max_variation {
        if !(v.is_finite() && v > 0.0) {
            bail!("--max-variation must be a finite number of bar/s > 0 (got {v})");
        }
    }
    let plant_cfg = load_plant(plant)?;
    let opts = pma_sim::tune::FireflyOptions {
        population: search.population,
        generations: search.generations,
        seed: search.seed,
        ..Default::default()
    };
    let objective = pma_sim::tune::Objective {
        duration_s: search.duration,
        max_variation_pa_per_s: search.max_variation.map(|v| v * 1e5),
    };
    let Some(res) = pma_sim::tune::tune(kind, &plant_cfg, &opts, &objective) else {
        bail!("{kind} has no search space here (pass --gains to change its gains)");
    };
    let (iae, var) = (res.score.iae_m, res.score.variation_pa_per_s / 1e5);
    if !res.feasible {
        bail!(
            "{kind}: no gain set within the budget found after {} runs (best: {var:.2} bar/s, IAE {iae:.4e} m)",
            res.evaluations
        );
    }
    let text = format!(
        "# Tuned by `{}`\n# ({} runs, sine IAE {iae:.4e} m, command variation {var:.3} bar/s)\n{}",
        search.command(kind, &plant_cfg.name),
        res.evaluations,
        res.config.to_toml_string()
    );
    match out {
        Some(p) => {
            std::fs::write(p, &text).with_context(|| format!("cannot write `{}`", p.display()))?
        }
        None => print!("{text}"),
    }
    eprintln!(
        "{kind}: IAE {iae:.4e} m, {var:.3} bar/s after {} runs",
        res.evaluations
    );
    Ok(())
}

fn tune_leg(
    scenario: &str,
    population: usize,
    generations: usize,
    duration: f64,
    seed: u64,
) -> Result<()> {
    check_duration(duration)?;
    if population < 2 {
        bail!("--population must be at least 2 (got {population})");
    }
    let loaded = pma_leg::Scenario::load(scenario)?;
    let opts = pma_sim::tune::FireflyOptions {
        population,
        generations,
        seed,
        ..Default::default()
    };
    let (gains, best, runs) = pma_leg::tune::tune(&loaded, &opts, duration);
    let table = toml::to_string(&gains).context("serialising the gains")?;
    println!(
        "# `pma-exo tune-leg {scenario} --population {population} --generations {generations} --duration {duration} --seed {seed}`:\n# {runs} runs, objective {best:.4} (hip RMS + knee RMS in deg + 0.01 x bar/s)\n[control.gains]\n{table}"
    );
    Ok(())
}
