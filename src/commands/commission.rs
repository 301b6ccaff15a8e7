//! `pma-exo rig commission`: excite, identify, tune robustly and verify, in one command.
use super::rig::check_rig_wall_time;
use crate::output::{self, OutFile};
use crate::say;
use anyhow::{bail, Context, Result};
use pma_control::{ControllerConfig, ControllerKind};
use pma_rig::{RigConfig, RunOptions};
use pma_studies::experiments::paper::{Plot, Varied};
use pma_studies::experiments::Series;
use pma_studies::identify::{identify_logs, read_log, Identified};
use pma_studies::tune::{robust_plants, tune_robust, Aggregate, FireflyOptions, Objective};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

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
    /// Seconds of excitation.
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
    /// Seed of the tuning and the bootstrap.
    #[arg(long, default_value_t = 2019)]
    seed: u64,
    /// Do not ask before the stages that move the muscle (a real board asks).
    #[arg(long)]
    yes: bool,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

/// What `--json` prints.
#[derive(serde::Serialize)]
struct Report<'a> {
    config: &'a str,
    controller: &'static str,
    rte_before_percent: f64,
    rte_told_percent: f64,
    rte_tuned_percent: f64,
    /// Why the supervisor stopped a verification run, if it did.
    told_fault: Option<String>,
    tuned_fault: Option<String>,
    rte_after_percent: f64,
    kept: &'static str,
    plant: String,
    gains: String,
    report: String,
    identified: &'a Identified,
}

/// Asks on the terminal before a stage that moves a real muscle.
fn confirm(stage: &str, real: bool, yes: bool) -> Result<()> {
    if !real || yes {
        return Ok(());
    }
    if !super::answered_yes(&format!(
        "{stage}: the muscle will move. Air on, area clear?"
    ))? {
        bail!("commissioning stopped before `{stage}`: not confirmed");
    }
    Ok(())
}

/// One supervised rig run: its measured RTE, or why the supervisor stopped it (vented).
fn rig_outcome(
    cfg: &RigConfig,
    dir: &Path,
    options: &RunOptions,
) -> Result<std::result::Result<f64, String>> {
    let stop = output::stop_flag()?;
    let report = pma_rig::run::run(cfg, dir, options, &stop, ())?;
    super::rig::warn_if_not_vented(&report);
    Ok(match &report.fault {
        Some(f) => Err(format!(
            "{f} ({}); log {}",
            report.fault_detail.as_deref().unwrap_or(""),
            report.log
        )),
        None => Ok(report.rte_percent),
    })
}

/// One supervised rig run that must complete; its measured RTE.
fn rig_run(cfg: &RigConfig, dir: &Path, options: &RunOptions, what: &str) -> Result<f64> {
    rig_outcome(cfg, dir, options)?.map_err(|f| anyhow::anyhow!("{what} stopped: {f}"))
}

/// Runs `rig commission`.
pub fn run(a: Args) -> Result<i32> {
    let (cfg, dir) = RigConfig::load(&a.config)?;
    let real = cfg.virtual_rig.is_none();
    if a.out.exists() {
        bail!(
            "`{}` exists: commissioning writes into a new directory (nothing is overwritten)",
            a.out.display()
        );
    }
    if !(a.max_variation.is_finite() && a.max_variation > 0.0) {
        bail!("--max-variation must be a finite number of bar/s > 0");
    }
    if !(1..=1000).contains(&a.robust) || a.population < 2 || a.generations < 1 {
        bail!("--robust must be 1..=1000, --population at least 2, --generations at least 1");
    }
    let load_kg = a.load_kg.or(cfg.load.mass_kg);
    let added = match (load_kg, a.added_mass_kg) {
        (None, None) => bail!(
            "the load is not known: pass --load-kg (weighed), set [load] mass_kg in the rig configuration, or pass --added-mass-kg M for a second excitation with M kg added"
        ),
        (Some(_), Some(_)) => bail!(
            "--added-mass-kg is for an unweighed load; the configuration's [load] mass_kg is set"
        ),
        (_, added) => added,
    };
    // Fails before anything moves if the added mass is not a valid mass.
    let cfg_added = added
        .map(|m| {
            let mut c = cfg.clone();
            c.load.added_mass_kg += m;
            c.validate().map(|()| c)
        })
        .transpose()
        .context("--added-mass-kg")?;
    let excitations = if added.is_some() { 2.0 } else { 1.0 };
    check_rig_wall_time(
        &cfg,
        cfg.duration_s * 4.0 + excitations * a.excite_duration,
        false,
        a.yes,
    )?;
    let configured = cfg.control_kind()?;
    let kind = a.controller.unwrap_or(configured);
    // Another controller than the configured one starts from its defaults.
    let current = if kind == configured {
        cfg.control.controller_config(kind, &dir)?
    } else {
        kind.default_config()
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create `{}`", a.out.display()))?;
    let path = |name: &str| a.out.join(name);
    let stage = |n: u32, what: &str| eprintln!("[{n}/5] {what}");

    stage(1, "the current controller, as configured");
    confirm("the run before", real, a.yes)?;
    let base = RunOptions {
        controller: Some(current),
        log_path: Some(path("before.csv")),
        ..RunOptions::default()
    };
    let rte_before = rig_run(&cfg, &dir, &base, "the run before")?;

    stage(2, "excitation");
    confirm("the excitation", real, a.yes)?;
    let excite = RunOptions {
        duration_s: Some(a.excite_duration),
        log_path: Some(path("excite.csv")),
        excitation: Some(cfg.default_excitation(a.excite_duration)),
        ..RunOptions::default()
    };
    rig_run(&cfg, &dir, &excite, "the excitation")?;
    let mut logs = vec![read_log(&path("excite.csv"))?];
    if let (Some(m), Some(cfg_added)) = (added, &cfg_added) {
        confirm(
            &format!("the excitation with {m} kg more on the load (hang it now)"),
            real,
            a.yes,
        )?;
        let o = RunOptions {
            log_path: Some(path("excite-added-mass.csv")),
            ..excite.clone()
        };
        rig_run(cfg_added, &dir, &o, "the excitation with the added mass")?;
        logs.push(read_log(&path("excite-added-mass.csv"))?);
    }

    stage(3, "identification");
    let log = &logs[0];
    let id = identify_logs(&logs, load_kg, a.seed)?;
    if id.fit_percent < 90.0 {
        bail!(
            "the identified model fits the held-out quarter at {:.1} % only: stopping before tuning (see {})",
            id.fit_percent,
            path("excite.csv").display()
        );
    }
    let plant = id.plant_config(log);
    OutFile::create(&path("plant.toml"))?
        .finish_with(&toml::to_string(&plant).context("cannot serialise the plant")?)?;

    stage(
        4,
        &format!(
            "robust tuning of {kind} on {} plants (about {:.0} s on this machine's cores)",
            a.robust,
            // 6 ms per 20 s run measured here (release, 2 cores).
            0.006 * (a.robust * a.population * (a.generations + 1)) as f64
                / rayon::current_num_threads() as f64
        ),
    );
    let plants = robust_plants(&plant, a.robust, a.spread, a.seed)?;
    let objective = Objective {
        duration_s: 20.0,
        max_variation_pa_per_s: Some(a.max_variation * 1e5),
    };
    let opts = FireflyOptions {
        population: a.population,
        generations: a.generations,
        seed: a.seed,
        ..FireflyOptions::default()
    };
    let stop = AtomicBool::new(false);
    let tuned = tune_robust(kind, &plants, Aggregate::Mean, &opts, &objective, &stop)
        .map(|(r, _)| r)
        .filter(|r| r.feasible);

    stage(5, "verification with the identified plant told");
    let mut told = cfg.clone();
    told.control.nominal = plant.nominal;
    confirm("the verification", real, a.yes)?;
    // A gain set the supervisor stops (the muscle out of its window, say) is a result:
    // it is not kept, and the other is verified all the same.
    let verify = |gains: ControllerConfig, log: &str| -> Result<(f64, Option<String>)> {
        let o = RunOptions {
            controller: Some(gains),
            log_path: Some(path(log)),
            ..RunOptions::default()
        };
        Ok(match rig_outcome(&told, &dir, &o)? {
            Ok(rte) => (rte, None),
            Err(fault) => {
                eprintln!("the verification with {log} stopped: {fault}");
                (f64::INFINITY, Some(fault))
            }
        })
    };
    let (rte_told, told_fault) = verify(current, "after-current-gains.csv")?;
    let (rte_tuned, tuned_fault) = match &tuned {
        Some(t) => verify(t.config, "after-tuned-gains.csv")?,
        None => (f64::INFINITY, None),
    };
    if told_fault.is_some() && (tuned.is_none() || tuned_fault.is_some()) {
        bail!(
            "no gain set completed the verification (see {}): the rig keeps its configuration",
            a.out.display()
        );
    }
    // The tuned gains are kept only if the rig says they are better.
    let (kept, gains, rte_after) = match &tuned {
        Some(t) if rte_tuned < rte_told => ("tuned", t.config, rte_tuned),
        _ => ("current", current, rte_told),
    };
    OutFile::create(&path("gains.toml"))?.finish_with(&format!(
        "# `pma-exo rig commission` ({kept} gains; RTE {rte_after:.3} % on the rig told the identified plant)\n{}",
        gains.to_toml_string()
    ))?;
    draw_plots(&a.out, kind, &id, log, tuned.is_some())?;
    let faults = [told_fault.as_deref(), tuned_fault.as_deref()];
    let provenance = crate::provenance::Provenance {
        plant: Some(format!("rig `{}` ({})", cfg.name, a.config)),
        controller: Some(kind.as_str().to_owned()),
        gains: Some(format!("{kept} (gains.toml)")),
        seeds: crate::provenance::Seeds::of("bootstrap and tuning", a.seed),
        ..crate::provenance::Provenance::of_this_run()
    };
    let md = format!(
        "{}\n_{}_\n",
        report_md(
            &a,
            kind,
            &id,
            [rte_before, rte_told, rte_tuned],
            faults,
            kept
        ),
        provenance.line()
    );
    OutFile::create(&path("report.md"))?.finish_with(&md)?;
    let report = Report {
        config: &a.config,
        controller: kind.as_str(),
        rte_before_percent: rte_before,
        rte_told_percent: rte_told,
        rte_tuned_percent: rte_tuned,
        told_fault,
        tuned_fault,
        rte_after_percent: rte_after,
        kept,
        plant: path("plant.toml").display().to_string(),
        gains: path("gains.toml").display().to_string(),
        report: path("report.md").display().to_string(),
        identified: &id,
    };
    if a.json {
        say!("{}", provenance.attach(&report)?);
    } else {
        say!(
            "commissioned {kind} on `{}`: RTE {rte_before:.2} % before, {rte_after:.2} % after ({kept} gains); wrote {}",
            a.config,
            a.out.display()
        );
    }
    Ok(0)
}

/// `t_s`, `reference_m` and `position_m` of a rig log's periods, every 10th.
fn log_series(path: &Path, label: &str) -> Result<Series> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)
        .with_context(|| format!("cannot read `{}`", path.display()))?;
    let names = reader.headers()?.clone();
    let col = |n: &str| {
        names
            .iter()
            .position(|c| c == n)
            .with_context(|| format!("`{}` has no `{n}` column", path.display()))
    };
    let (t, r, x, e) = (
        col("t_s")?,
        col("reference_m")?,
        col("position_m")?,
        col("event")?,
    );
    let mut series = Series {
        label: label.to_owned(),
        ..Series::default()
    };
    for (k, row) in reader.records().enumerate() {
        let row = row?;
        if k % 10 != 0 || &row[e] == "vent" {
            continue;
        }
        let num = |c: usize| row[c].parse::<f64>().unwrap_or(f64::NAN);
        series.t_s.push(num(t));
        series.reference_m.push(num(r));
        series.position_m.push(num(x));
    }
    Ok(series)
}

/// `tracking.png` (the rig's runs against the reference) and `identification.png` (the
/// measured excitation against the identified model, open loop).
fn draw_plots(
    dir: &Path,
    kind: ControllerKind,
    id: &Identified,
    log: &pma_studies::identify::IdLog,
    tuned: bool,
) -> Result<()> {
    crate::plot::register_font()?;
    let mut runs = vec![
        log_series(&dir.join("before.csv"), "before")?,
        log_series(&dir.join("after-current-gains.csv"), "after, same gains")?,
    ];
    if tuned {
        runs.push(log_series(
            &dir.join("after-tuned-gains.csv"),
            "after, tuned gains",
        )?);
    }
    let tracking = Plot {
        name: "tracking",
        title: format!("Commissioning {kind}: the rig's measured position"),
        setting: "before: as configured; after: the identified plant told (report.md)".into(),
        legend_title: "run".into(),
        varied: Varied::Controller,
        events: Vec::new(),
        series: runs,
    };
    let simulated = id.simulated_position_m(log).unwrap_or_default();
    let t_s: Vec<f64> = (1..=simulated.len())
        .map(|k| k as f64 * log.period_s)
        .collect();
    let decimate = |v: &[f64]| v.iter().step_by(10).copied().collect::<Vec<f64>>();
    let held_out_s = log.duration_s() * 0.75;
    let identification = Plot {
        name: "identification",
        title: "Identification: the excitation measured (grey) and the identified model".into(),
        setting: format!(
            "open loop from rest; fitted to {held_out_s:.0} s, held out after (fit {:.2} %)",
            id.fit_percent
        ),
        legend_title: "model".into(),
        varied: Varied::Setting,
        events: vec![(held_out_s, "held out".into())],
        series: vec![Series {
            label: "identified".into(),
            t_s: decimate(&t_s),
            reference_m: decimate(&log.position_m),
            position_m: decimate(&simulated),
        }],
    };
    for plot in [tracking, identification] {
        let path = dir.join(format!("{}.png", plot.name));
        output::write_via_temp(&path, |tmp| crate::plot::draw(tmp, &plot))?;
    }
    Ok(())
}

fn report_md(
    a: &Args,
    kind: ControllerKind,
    id: &Identified,
    rte: [f64; 3],
    faults: [Option<&str>; 2],
    kept: &str,
) -> String {
    let cell = |rte: f64, fault: Option<&str>| match fault {
        Some(f) => format!("stopped by the supervisor: {f}"),
        None if rte.is_finite() => format!("{rte:.3} %"),
        None => "no gain set within the budget".into(),
    };
    let mut md = format!(
        "# Commissioning of {kind} on `{}`\n\n\
         Load {:.3} kg ({}). Excitation {} s (`excite.csv`{}), identification (`plant.toml`), \
         robust tuning on {} plants within {} % (`gains.toml` if it won), verification on the rig.\n\n\
         | run | RTE (measured position) |\n|---|---|\n\
         | before: configured gains and nominal (`before.csv`) | {:.3} % |\n\
         | configured gains, identified plant told (`after-current-gains.csv`) | {} |\n\
         | robustly tuned gains, identified plant told (`after-tuned-gains.csv`) | {} |\n\n\
         Kept: the {kept} gains.\n\n![tracking](tracking.png)\n\n## Identification\n\n![identification](identification.png)\n\n\
         Valve {:.2} ms + {:.2} ms dead time; held-out fit {:.2} % ({:.1} um RMS); residual {:.1} um RMS; \
         condition number {:.0}. {}\n\n| parameter | estimate | 95 % interval | Table I / nominal |\n|---|---|---|---|\n",
        a.config,
        id.load_mass_kg,
        id.load_source,
        a.excite_duration,
        if id.logs > 1 {
            ", and `excite-added-mass.csv` with the added mass"
        } else {
            ""
        },
        a.robust,
        a.spread * 100.0,
        rte[0],
        cell(rte[1], faults[0]),
        cell(rte[2], faults[1]),
        id.valve_time_constant_s * 1e3,
        id.valve_dead_time_s * 1e3,
        id.fit_percent,
        id.rms_error_m * 1e6,
        id.noise_rms_m * 1e6,
        id.condition_number,
        id.force_scale,
    );
    for (name, e) in &id.parameters {
        let nominal = if name.ends_with("_scale") { "1" } else { "0" };
        md.push_str(&format!(
            "| {name} | {:.4} | [{:.4}, {:.4}] | {nominal} |\n",
            e.value, e.low, e.high
        ));
    }
    for (p, q, rho) in &id.inseparable {
        md.push_str(&format!(
            "\n- not separable by these data: {p} and {q} (correlation {rho:.3})"
        ));
    }
    md.push('\n');
    md
}
