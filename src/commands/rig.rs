//! `pma-exo rig`: the hardware backend (check, run, replay).
use super::{viz, RerunArgs};
use crate::output;
use crate::say;
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use pma_control::ControllerKind;
use pma_rig::config::ClockMode;
use pma_rig::{Injection, RigConfig, RunOptions};
use std::path::PathBuf;

/// Wall time of one lockstep period of the virtual rig, log included (s): measured 4.7 us
/// (600 s run) to 6.5 us (20 s run, start-up included) with a release build on the 2-core
/// development VM (`docs/safety.md`).
const LOCKSTEP_PERIOD_S: f64 = 6.5e-6;

/// `rig` subcommands.
#[derive(Subcommand)]
pub enum RigCommand {
    /// Configure only: open and check the board, write the vent value, read the sensor;
    /// print the reading, calibration and limits. No air is commanded.
    Check {
        /// Rig configuration: `virtual` (default), `pci6052e`, or a .toml file.
        #[arg(long, default_value = "virtual")]
        config: String,
    },
    /// Run the controller on the rig, supervised, logged, vented at the end.
    Run {
        /// Rig configuration: `virtual` (default), `pci6052e`, or a .toml file.
        #[arg(long, default_value = "virtual")]
        config: String,
        /// Seconds (default: the configuration's).
        #[arg(long, allow_negative_numbers = true)]
        duration: Option<f64>,
        /// Controller instead of the configuration's.
        #[arg(long, value_name = ControllerKind::NAMES)]
        controller: Option<ControllerKind>,
        /// Gain file for the controller (without --controller: the file's controller).
        #[arg(long)]
        gains: Option<PathBuf>,
        /// Inject a fault into the virtual rig at T seconds (0 < T < the duration):
        /// sensor-nan, sensor-stuck, position-out, daq-error, stall, controller-panic, or
        /// pressure-high (with the pressure channel) (repeatable).
        #[arg(long, value_name = "FAULT@T")]
        inject: Vec<Injection>,
        /// Virtual rig: run on wall-clock deadlines (1 kHz) instead of lockstep.
        #[arg(long)]
        realtime: bool,
        /// Do not ask for SCHED_FIFO and mlockall (timer slack 1 ns only).
        #[arg(long)]
        no_fifo: bool,
        /// CSV log path instead of the configuration's (`{time}` is replaced by the UTC
        /// start); an existing file is never overwritten.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
        /// Run even if it would take over an hour.
        #[arg(long)]
        yes: bool,
        #[command(flatten)]
        rerun: RerunArgs,
    },
    /// Excite the muscle open loop for identification, supervised and logged like `run`
    /// (same log format, vented at the end): pressure steps up and down, then a 0.05-3 Hz
    /// chirp, between 0.5 bar and half the pressure limit, backing off when the position
    /// nears its window.
    Excite {
        /// Rig configuration: `virtual` (default), `pci6052e`, or a .toml file.
        #[arg(long, default_value = "virtual")]
        config: String,
        /// The log to write (CSV, as `rig run --log`); an existing file is never overwritten.
        #[arg(long)]
        out: PathBuf,
        /// Seconds of excitation.
        #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
        duration: f64,
        /// A known mass added to the load for this excitation (kg): the second run of the
        /// added-mass protocol when the load is not weighed (`identify LOG1 LOG2`). The
        /// virtual rig hangs it itself; a real rig asks you to (`--yes` skips the question).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        added_mass_kg: f64,
        /// Virtual rig: run on wall-clock deadlines (1 kHz) instead of lockstep.
        #[arg(long)]
        realtime: bool,
        /// Do not ask for SCHED_FIFO and mlockall (timer slack 1 ns only).
        #[arg(long)]
        no_fifo: bool,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
        /// Run even if it would take over an hour; do not ask for the added mass.
        #[arg(long)]
        yes: bool,
    },
    /// Commission the muscle in one command: the configured controller, an excitation,
    /// identification, a robust tuning on the identified plant, and a verification on
    /// the rig; a report in a new directory. A real board asks before each stage that
    /// moves the muscle (`--yes` skips).
    Commission(super::commission::Args),
    /// Feed a log's measurements, references and periods back through the same
    /// controller and report the largest difference from the logged commands.
    Replay {
        /// The log (CSV written by `rig run`).
        log: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// Runs a `rig` subcommand; returns the process exit status.
pub fn run(cmd: RigCommand) -> Result<i32> {
    match cmd {
        RigCommand::Check { config } => check(&config).map(|()| 0),
        RigCommand::Run {
            config,
            duration,
            controller,
            gains,
            inject,
            realtime,
            no_fifo,
            log,
            json,
            yes,
            rerun,
        } => {
            let (cfg, dir) = RigConfig::load(&config)?;
            let controller_cfg = match (controller, gains.as_deref()) {
                (None, None) => None,
                (kind, path) => {
                    let kind = match kind {
                        Some(k) => k,
                        // A gain file says which controller it is (as for `single`).
                        None => super::kind_of_gains(path, cfg.control_kind()?)?,
                    };
                    Some(super::load_gains(kind, path)?)
                }
            };
            let mut options = RunOptions {
                duration_s: duration,
                controller: controller_cfg,
                injections: inject,
                clock: realtime.then_some(ClockMode::Realtime),
                log_path: log,
                fifo: no_fifo.then_some(false),
                ..RunOptions::default()
            };
            refuse_overwrites(&cfg, &config, &options, gains.as_deref(), &rerun)?;
            let duration = options.duration_s.unwrap_or(cfg.duration_s);
            check_rig_wall_time(&cfg, duration, realtime, yes)?;
            let provenance = rig_provenance(&cfg, &config, &options, gains.as_deref())?;
            options.provenance = Some(provenance.line());
            run_rig(&cfg, &dir, &options, json, &rerun, &provenance)
                .with_context(|| format!("rig configuration `{config}`"))
        }
        RigCommand::Excite {
            config,
            out,
            duration,
            added_mass_kg,
            realtime,
            no_fifo,
            json,
            yes,
        } => {
            let (cfg, dir) = RigConfig::load(&config)?;
            let cfg = with_added_mass(cfg, added_mass_kg, yes)?;
            check_rig_wall_time(&cfg, duration, realtime, yes)?;
            let mut options = RunOptions {
                duration_s: Some(duration),
                clock: realtime.then_some(ClockMode::Realtime),
                log_path: Some(out),
                fifo: no_fifo.then_some(false),
                excitation: Some(cfg.default_excitation(duration)),
                ..RunOptions::default()
            };
            let rerun = RerunArgs::default();
            refuse_overwrites(&cfg, &config, &options, None, &rerun)?;
            let provenance = rig_provenance(&cfg, &config, &options, None)?;
            options.provenance = Some(provenance.line());
            run_rig(&cfg, &dir, &options, json, &rerun, &provenance)
                .with_context(|| format!("rig configuration `{config}`"))
        }
        RigCommand::Commission(a) => super::commission::run(a),
        RigCommand::Replay { log, json } => {
            let r = pma_rig::replay(&log)?;
            if json {
                say!("{}", serde_json::to_string(&r)?);
            } else {
                say!(
                    "replayed {} periods of {} from `{}`: largest command difference {} Pa, {} periods differ",
                    r.periods,
                    r.controller,
                    r.log,
                    r.max_abs_difference_pa,
                    r.mismatches
                );
            }
            Ok(if r.mismatches == 0 { 0 } else { 4 })
        }
    }
}

/// The configuration with `added_kg` hung on the load (validated); a real rig asks the
/// user to hang it first unless `yes`.
pub(crate) fn with_added_mass(mut cfg: RigConfig, added_kg: f64, yes: bool) -> Result<RigConfig> {
    if added_kg == 0.0 {
        return Ok(cfg);
    }
    cfg.load.added_mass_kg += added_kg;
    cfg.validate().context("--added-mass-kg")?;
    let asked = cfg.virtual_rig.is_none() && !yes;
    if asked
        && !super::answered_yes(&format!(
            "Hang {added_kg} kg more on the load (weighed), then excite with it?"
        ))?
    {
        bail!("the excitation with the added mass was not confirmed: nothing ran");
    }
    Ok(cfg)
}

/// Refuses a run over an hour of wall time unless `yes`; anything but a lockstep virtual
/// run takes real time.
pub(crate) fn check_rig_wall_time(
    cfg: &RigConfig,
    duration_s: f64,
    realtime: bool,
    yes: bool,
) -> Result<()> {
    super::check_duration(duration_s)?;
    let lockstep = !realtime
        && cfg
            .virtual_rig
            .as_ref()
            .is_some_and(|v| v.clock == ClockMode::Lockstep);
    let per_period_s = if lockstep {
        LOCKSTEP_PERIOD_S
    } else {
        cfg.period_s
    };
    output::check_wall_time("this rig run", duration_s / cfg.period_s, per_period_s, yes)
}

fn check(config: &str) -> Result<()> {
    let (cfg, _) = RigConfig::load(config)?;
    let backend =
        pma_rig::run::check(&cfg).with_context(|| format!("rig configuration `{config}`"))?;
    let c = &cfg.calibration;
    let l = &cfg.limits;
    let x = backend.configure_reading_m();
    say!(
        "rig `{}` on `{}`: board checked, valve vented ({} V)",
        cfg.name,
        backend.device(),
        backend.vent_v()
    );
    say!(
        "  position: {:.3} mm ({:.4} V; calibration {} m/V, {:.4} V at 0 m)",
        x * 1e3,
        c.position_v(x),
        c.position_m_per_v,
        c.position_offset_v
    );
    if let Some(p) = backend.pressure_reading_pa() {
        let highest_pa = (1.0 + pma_rig::backend::PRESSURE_FAULT_MARGIN) * l.pressure_max_pa;
        say!(
            "  pressure channel: {:.3} bar ({} Pa/V, {:.4} V at 0 Pa); a reading above {:.2} bar ({:.4} V) stops a run",
            p / 1e5,
            c.pressure_scale_pa_per_v(),
            c.pressure_zero_v(),
            highest_pa / 1e5,
            c.pressure_v(highest_pa)
        );
    }
    say!(
        "  valve: {} Pa/V, {} V at 0 Pa; 0..{} bar is {}..{} V",
        c.valve_pa_per_v,
        c.valve_offset_v,
        l.pressure_max_pa / 1e5,
        c.valve_v(0.0),
        c.valve_v(l.pressure_max_pa)
    );
    say!(
        "  limits: position {}..{} mm, rate {} bar/s, stuck after {} periods, watchdog {} periods of {} ms",
        l.position_min_m * 1e3,
        l.position_max_m * 1e3,
        l.pressure_rate_max_pa_per_s / 1e5,
        l.sensor_stuck_periods,
        l.watchdog_periods,
        cfg.period_s * 1e3
    );
    Ok(())
}

/// Refuses a run whose log would be one of its inputs or its Rerun recording (up front:
/// the log is created by the run, and the recording renamed onto its path at the end).
fn refuse_overwrites(
    cfg: &RigConfig,
    config: &str,
    options: &RunOptions,
    gains: Option<&std::path::Path>,
    rerun: &RerunArgs,
) -> Result<()> {
    let log = options.log_path.as_ref().unwrap_or(&cfg.log_path);
    let flag = if options.excitation.is_some() {
        "--out"
    } else {
        "--log"
    };
    let mut outputs = vec![(flag, log.as_path())];
    if let Some(rrd) = rerun.save_path() {
        outputs.push(("--rerun save", rrd));
    }
    let mut inputs = Vec::new();
    if let Some(c) = output::input_file(config) {
        inputs.push(("rig configuration", c));
    }
    if let Some(g) = gains {
        inputs.push(("gain file", g));
    }
    output::refuse_input_as_output(&inputs, &outputs)
}

fn run_rig(
    cfg: &RigConfig,
    dir: &std::path::Path,
    options: &RunOptions,
    json: bool,
    rerun: &RerunArgs,
    provenance: &crate::provenance::Provenance,
) -> Result<i32> {
    let stop = output::stop_flag()?;
    let meta = format!(
        "# rig `{}`\n\n{}\n\n{}\n",
        cfg.name,
        cfg.description,
        provenance.line()
    );
    let mut viz = viz::bench(rerun, "pma-exo rig", cfg.period_s, &meta)?;
    // Real time: a bar over the periods (a lockstep run is over before one would draw).
    let realtime = options.clock == Some(ClockMode::Realtime)
        || cfg.virtual_rig.is_none()
        || cfg
            .virtual_rig
            .as_ref()
            .is_some_and(|v| v.clock == ClockMode::Realtime);
    let duration = options.duration_s.unwrap_or(cfg.duration_s);
    let progress = realtime.then(|| super::Progress::new((duration / cfg.period_s) as u64));
    let bar = progress.as_ref().map(|p| p.bar.clone());
    let report = pma_rig::run::run(cfg, dir, options, &stop, (&mut viz, progress));
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let report = report?;
    if let Err(e) = viz::finish(viz) {
        eprintln!("warning: Rerun: {e}");
    }
    warn_if_not_vented(&report);
    if json {
        say!("{}", provenance.attach(&report)?);
    } else {
        print_report(&report)?;
        say!("  ({})", provenance.line());
    }
    if let Some(e) = &report.log_error {
        eprintln!("error: the log `{}` is incomplete: {e}", report.log);
    }
    Ok(report.exit_code())
}

/// What a rig run runs: the rig (its file by path), its plant (virtual) or device, the
/// controller, where its gains come from, and the virtual sensor's noise seed.
fn rig_provenance(
    cfg: &RigConfig,
    config: &str,
    options: &RunOptions,
    gains_file: Option<&std::path::Path>,
) -> Result<crate::provenance::Provenance> {
    let controller = if options.excitation.is_some() {
        "excitation (open loop)".to_owned()
    } else {
        match &options.controller {
            Some(c) => c.kind().as_str().to_owned(),
            None => cfg.control.controller.clone(),
        }
    };
    let gains = match (&options.controller, &cfg.control.gains) {
        _ if options.excitation.is_some() => None,
        (Some(_), _) => Some(match gains_file {
            Some(path) => path.display().to_string(),
            None => "the controller's defaults (--controller)".to_owned(),
        }),
        (None, Some(path)) => Some(path.display().to_string()),
        (None, None) => Some("the controller's defaults (APRC-NDO: the paper's)".to_owned()),
    };
    let rig = crate::provenance::named(config, &cfg.name);
    let (plant, seeds) = match &cfg.virtual_rig {
        Some(v) => {
            let seeds = if v.sensor_noise_rms_m > 0.0 {
                let plant = pma_bench::PlantConfig::load(&v.plant)?;
                crate::provenance::Seeds::of("virtual sensor noise", plant.sensor.seed)
            } else {
                crate::provenance::Seeds::default()
            };
            (format!("virtual rig {rig} with plant {}", v.plant), seeds)
        }
        None => (
            format!("rig {rig} on {}", cfg.device.path),
            crate::provenance::Seeds::default(),
        ),
    };
    Ok(crate::provenance::Provenance {
        plant: Some(plant),
        controller: Some(controller),
        gains,
        seeds,
        ..crate::provenance::Provenance::of_this_run()
    })
}

/// The one message a run that could not vent must print, whatever else happens.
pub(crate) fn warn_if_not_vented(report: &pma_rig::RigReport) {
    if !report.vented {
        eprintln!(
            "DANGER: the valve could not be vented at the end of the run: dump the air by hand"
        );
    }
}

fn print_report(r: &pma_rig::RigReport) -> Result<()> {
    let status = match (&r.fault, r.completed) {
        (None, true) => "completed".to_owned(),
        (Some(f), _) => format!("stopped: {f}"),
        (None, false) => "stopped".to_owned(),
    };
    say!(
        "rig `{}` ({} {}, {}): {status}, {} periods, vented: {}",
        r.config,
        r.driver,
        r.clock,
        r.controller,
        r.periods,
        r.vented
    );
    if let Some(d) = &r.fault_detail {
        say!("  {d}");
    }
    if r.controller == "excite" {
        say!("  an open-loop excitation: no tracking figures (identify from the log)");
    } else {
        say!(
            "  tracking (measured): MAE {:.3e} m, IAE {:.3e} m, RTE {:.3} %",
            r.mae_m,
            r.iae_m,
            r.rte_percent
        );
    }
    if r.clock == "realtime" {
        say!(
            "  timing: {} overruns, wake-up jitter p50 {:.0} us, p99 {:.0} us, max {:.0} us; compute p50 {:.1} us, p99 {:.1} us; SCHED_FIFO: {}",
            r.overruns, r.jitter_p50_us, r.jitter_p99_us, r.jitter_max_us, r.compute_p50_us, r.compute_p99_us, r.realtime
        );
    }
    for w in &r.realtime_warnings {
        say!("  warning: {w}");
    }
    say!("  log: {} ({} rows)", r.log, r.log_rows);
    Ok(())
}
