//! `pma-exo rig`: the hardware backend (check, run, replay).
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use pma_control::ControllerKind;
use pma_loop::{MuscleStep, Period, Recorder};
use pma_rig::config::ClockMode;
use pma_rig::{Injection, Rig, RigConfig, RunOptions};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

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
        #[arg(long)]
        controller: Option<ControllerKind>,
        /// Gain file for the controller.
        #[arg(long)]
        gains: Option<PathBuf>,
        /// Inject a fault into the virtual rig at T seconds: sensor-nan, sensor-stuck,
        /// position-out, daq-error or stall (repeatable).
        #[arg(long, value_name = "FAULT@T")]
        inject: Vec<Injection>,
        /// Virtual rig: run on wall-clock deadlines (1 kHz) instead of lockstep.
        #[arg(long)]
        realtime: bool,
        /// Do not ask for SCHED_FIFO and mlockall (timer slack 1 ns only).
        #[arg(long)]
        no_fifo: bool,
        /// CSV log path instead of the configuration's.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Print one JSON object instead of the summary.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        rerun: crate::RerunArgs,
    },
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
            rerun,
        } => {
            let (cfg, dir) = RigConfig::load(&config)?;
            let controller_cfg = match (controller, gains.as_deref()) {
                (None, None) => None,
                (kind, path) => {
                    let kind = match kind {
                        Some(k) => k,
                        None => cfg.control_kind()?,
                    };
                    Some(crate::load_gains(kind, path)?)
                }
            };
            let options = RunOptions {
                duration_s: duration,
                controller: controller_cfg,
                injections: inject,
                clock: realtime.then_some(ClockMode::Realtime),
                log_path: log,
                fifo: no_fifo.then_some(false),
            };
            run_rig(&cfg, &dir, &options, json, &rerun)
        }
        RigCommand::Replay { log, json } => {
            let r = pma_rig::replay(&log)?;
            if json {
                println!("{}", serde_json::to_string(&r)?);
            } else {
                println!(
                    "replayed {} periods of {} from `{}`: largest command difference {} Pa, {} periods differ",
                    r.periods, r.controller, r.log, r.max_abs_difference_pa, r.mismatches
                );
            }
            Ok(if r.mismatches == 0 { 0 } else { 4 })
        }
    }
}

fn check(config: &str) -> Result<()> {
    let (cfg, _) = RigConfig::load(config)?;
    let backend = pma_rig::run::check(&cfg)?;
    let c = &cfg.calibration;
    let l = &cfg.limits;
    let x = backend.configure_reading_m();
    println!(
        "rig `{}` on `{}`: board checked, valve vented ({} V)",
        cfg.name,
        backend.device(),
        backend.vent_v()
    );
    println!(
        "  position: {:.3} mm ({:.4} V; calibration {} m/V, {} V at 0 m)",
        x * 1e3,
        c.position_v(x),
        c.position_m_per_v,
        c.position_offset_v
    );
    println!(
        "  valve: {} Pa/V, {} V at 0 Pa; 0..{} bar is {}..{} V",
        c.valve_pa_per_v,
        c.valve_offset_v,
        l.pressure_max_pa / 1e5,
        c.valve_v(0.0),
        c.valve_v(l.pressure_max_pa)
    );
    println!(
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

/// Logs rig periods to Rerun with the bench's layout (`muscles/muscle/...`).
struct RigViz {
    viz: pma_viz::Viz,
    step: i64,
    scalars: [f64; 11],
    error: Option<pma_viz::VizError>,
}

impl Recorder<Rig, MuscleStep> for RigViz {
    fn record(&mut self, p: &Period<'_, Rig, MuscleStep>) {
        self.step += 1;
        if self.step % self.viz.decimation() != 0 {
            return;
        }
        let sample = pma_sim::Sample {
            t_s: p.t_s,
            reference_m: p.output.reference.position_m,
            position_m: p.reading.position_m,
            measured_m: p.reading.position_m,
            pressure_cmd_pa: *p.written,
            // A rig does not measure the muscle's pressure or force.
            pressure_pa: f64::NAN,
            force_n: f64::NAN,
            diagnostics: p.output.control.diagnostics,
        };
        crate::viz::bench_scalars(&sample, &mut self.scalars);
        let frame = pma_viz::Frame {
            t_s: p.t_s,
            step: self.step,
            scalars: &self.scalars,
            link_poses: &[],
            muscle_lines: &[],
        };
        if let Err(e) = self.viz.push(&frame) {
            self.error.get_or_insert(e);
        }
    }
}

fn run_rig(
    cfg: &RigConfig,
    dir: &std::path::Path,
    options: &RunOptions,
    json: bool,
    rerun: &crate::RerunArgs,
) -> Result<i32> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .context("cannot install the SIGINT/SIGTERM handler")?;
    }
    let viz = crate::viz::open(&rerun.sink, "pma-exo rig", cfg.period_s, rerun.rerun_hz)?;
    let report = match viz {
        Some(mut v) => {
            let meta = format!("# rig `{}`\n\n{}\n", cfg.name, cfg.description);
            crate::viz::bench_layout(&mut v, &meta)?;
            let mut rec = RigViz {
                viz: v,
                step: 0,
                scalars: [0.0; 11],
                error: None,
            };
            let report = pma_rig::run::run(cfg, dir, options, &stop, &mut rec)?;
            if let Some(e) = rec.error.take() {
                eprintln!("warning: Rerun: {e}");
            }
            crate::viz::finish(Some(rec.viz))?;
            report
        }
        None => pma_rig::run::run(cfg, dir, options, &stop, ())?,
    };
    if !report.vented {
        eprintln!(
            "DANGER: the valve could not be vented at the end of the run: dump the air by hand"
        );
    }
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report);
    }
    if report.log_dropped > 0 {
        bail!(
            "the log lost {} records (the disk did not keep up): `{}` is incomplete",
            report.log_dropped,
            report.log
        );
    }
    Ok(report.exit_code())
}

fn print_report(r: &pma_rig::RigReport) {
    let status = match (&r.fault, r.completed) {
        (None, true) => "completed".to_owned(),
        (Some(f), _) => format!("stopped: {f}"),
        (None, false) => "stopped".to_owned(),
    };
    println!(
        "rig `{}` ({} {}, {}): {status}, {} periods, vented: {}",
        r.config, r.driver, r.clock, r.controller, r.periods, r.vented
    );
    if let Some(d) = &r.fault_detail {
        println!("  {d}");
    }
    println!(
        "  tracking (measured): MAE {:.3e} m, IAE {:.3e} m, RTE {:.3} %",
        r.mae_m, r.iae_m, r.rte_percent
    );
    if r.clock == "realtime" {
        println!(
            "  timing: {} overruns, wake-up jitter p50 {:.0} us, p99 {:.0} us, max {:.0} us; compute p50 {:.1} us, p99 {:.1} us; SCHED_FIFO: {}",
            r.overruns, r.jitter_p50_us, r.jitter_p99_us, r.jitter_max_us, r.compute_p50_us, r.compute_p99_us, r.realtime
        );
    }
    for w in &r.realtime_warnings {
        println!("  warning: {w}");
    }
    println!("  log: {} ({} rows)", r.log, r.log_rows);
}
