//! `pma-exo`: gait-training simulations of the exoskeleton leg, single-muscle runs, the
//! paper's experiments, gain tuning, and the hardware rig.
#![warn(clippy::print_stdout)]
use anyhow::Result;
use clap::{Parser, Subcommand};

mod commands;
mod output;
mod plot;
mod provenance;

use commands::{
    compare_leg, compare_modes, envelope, fit_gait, identify, impedance, pendulum, rig, simulate,
    single, size, sweep, tune, valve,
};

#[derive(Parser)]
#[command(
    name = "pma-exo",
    version,
    about = "Pneumatic-muscle control (APRC-NDO, Cao et al. 2020): simulation, experiments, rig"
)]
struct Cli {
    /// Without a subcommand: `simulate` (the default gait-training simulation).
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Gait training on the exoskeleton leg (rapier), four muscles under APRC-NDO.
    Simulate(simulate::Args),
    /// One controller on the single-muscle bench.
    Single(single::Args),
    /// Rerun the paper's experiments in simulation: results.json, report.md, plots.
    Paper {
        /// Output directory.
        #[arg(long, default_value = "paper-out")]
        out: std::path::PathBuf,
    },
    /// Tune a controller's gains with the firefly algorithm on the sine (IAE objective).
    Tune(tune::Args),
    /// Tune a controller's gains on a leg scenario with the same firefly search
    /// (objective: hip + knee RMS error, on a treadmill the worst foot's stance-phase RMS,
    /// plus 0.01 deg per bar/s of command variation).
    TuneLeg(tune::LegArgs),
    /// APRC-NDO, PSMC, NDO-SMC, STA and PID (leg gains tuned with one budget) on the
    /// patient scenarios: tracking, spasm deviation and recovery, pressure rates, safety.
    CompareLeg(compare_leg::Args),
    /// The Festo muscles and pulleys a scenario's gait needs: the joints' torques and
    /// speeds over a stride (inverse dynamics with the belt's forces), every DMSP size,
    /// length and pulley that supplies them, a recommendation and its muscles.toml.
    Size(size::Args),
    /// Where a treadmill scenario walks its patient: body mass x support x walking speed x
    /// mode, each cell walked, refused before it ran, or run and failed, with its reason;
    /// a table, a JSON and a map (envelope.png).
    Envelope(envelope::Args),
    /// A treadmill scenario's hip reference made consistent with its belt: servo-driven
    /// runs that change the hip where a stance foot runs ahead of or behind the belt, until
    /// it moves with it; prints (or writes) the scenario's `[gait.hip_correction]`.
    FitGait(fit_gait::Args),
    /// One patient under position, impedance, path and transparent control and with the
    /// muscles unhooked: interaction torques, work, the patient's stride variability, time
    /// in the tunnel, spasms (in the air).
    CompareModes(compare_modes::Args),
    /// The joint stiffness a scenario's muscle pairs reach by co-contraction (at rest,
    /// along a stride, at a test pose) and, for a leg in the air, small-perturbation tests
    /// of what impedance mode realises at three set points per joint.
    Impedance(impedance::Args),
    /// The Wartenberg pendulum test: thigh horizontal, knee released, muscles vented;
    /// R2, first swing, oscillations of the scenario's patient.
    Pendulum(pendulum::Args),
    /// Grids of bench runs (controllers x gains x plants x references x events x seeds)
    /// and leg runs (scenarios x controllers x gains x patients x seeds) in parallel, one
    /// JSON line per run; `--shard I/N` for job arrays; `sweep merge`.
    Sweep(sweep::Args),
    /// Identify the muscle, its valve and the sensor noise from a rig log (`rig excite`):
    /// a plant file for `single`, `tune` and the virtual rig, with intervals and a
    /// held-out fit.
    Identify(identify::Args),
    /// A pressure step of a Festo muscle behind a flow-limited valve (ISO 6358), its
    /// supply and tube: rise and fall times, peak pressure rates, the datasheet's source.
    Valve(valve::Args),
    /// The hardware backend: one muscle on a DAQ rig (or the virtual rig).
    Rig {
        #[command(subcommand)]
        command: rig::RigCommand,
    },
}

fn main() {
    let cli = match Cli::try_parse_from(rerun_save_joined(std::env::args_os())) {
        Ok(c) => c,
        Err(e) => exit_on_cli_error(&e),
    };
    match run(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) if e.downcast_ref::<output::StdoutClosed>().is_some() => std::process::exit(0),
        Err(e)
            if e.downcast_ref::<commands::paper::studies::Interrupted>()
                .is_some() =>
        {
            eprintln!(
                "interrupted: nothing was written over the previous results (the sweeps' runs so far are kept under the output's sweeps/; the same command resumes them)"
            );
            std::process::exit(output::INTERRUPTED);
        }
        Err(e) => {
            eprintln!("error: {}", pma_exo::error_line(&e));
            std::process::exit(1);
        }
    }
}

/// The command line with `--rerun save FILE` read as `--rerun save=FILE`: both spellings
/// are accepted (`save` alone means nothing, so the next argument can only be its file).
fn rerun_save_joined(
    args: impl IntoIterator<Item = std::ffi::OsString>,
) -> Vec<std::ffi::OsString> {
    let mut out: Vec<std::ffi::OsString> = Vec::new();
    let mut args = args.into_iter().peekable();
    while let Some(arg) = args.next() {
        let save_follows = match arg.to_str() {
            Some("--rerun") => args.peek().is_some_and(|a| a == "save"),
            Some("--rerun=save") => true,
            _ => false,
        };
        if !save_follows {
            out.push(arg);
            continue;
        }
        if arg == "--rerun" {
            args.next();
        }
        match args.peek() {
            Some(file) if !file.to_string_lossy().starts_with('-') => {
                let mut joined = std::ffi::OsString::from("save=");
                joined.push(file);
                args.next();
                out.extend(["--rerun".into(), joined]);
            }
            // No file: left to the parser, which says how to give one.
            _ => out.extend(["--rerun".into(), "save".into()]),
        }
    }
    out
}

/// Help and version as clap prints them; any other clap error on one line that keeps its
/// content (the missing argument with its values, the possible values, the suggestion).
fn exit_on_cli_error(e: &clap::Error) -> ! {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        let _ = e.print();
        std::process::exit(0);
    }
    eprintln!("{}", cli_error_line(&e.to_string()));
    std::process::exit(2);
}

/// Clap's multi-line message as one line: usage and "for more information" dropped.
fn cli_error_line(text: &str) -> String {
    let kept: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more information")
        })
        .collect();
    pma_control::text::one_line(&kept.join(" "))
}

fn run(cli: Cli) -> Result<i32> {
    match cli
        .command
        .unwrap_or_else(|| Command::Simulate(simulate::Args::default()))
    {
        Command::Simulate(a) => simulate::run(a),
        Command::Pendulum(a) => pendulum::run(a),
        Command::Single(a) => single::run(a),
        Command::Paper { out } => commands::paper::run(&out).map(|()| 0),
        Command::Tune(a) => tune::run(a),
        Command::TuneLeg(a) => tune::run_leg(a),
        Command::CompareLeg(a) => compare_leg::run(a),
        Command::Size(a) => size::run(a),
        Command::Envelope(a) => envelope::run(a),
        Command::FitGait(a) => fit_gait::run(a),
        Command::Impedance(a) => impedance::run(a),
        Command::CompareModes(a) => compare_modes::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Identify(a) => identify::run(a),
        Command::Valve(a) => valve::run(a),
        Command::Rig { command } => rig::run(command),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: `--rerun save FILE` failed with a bare "unexpected argument"; both
    /// spellings now record into FILE, and `save` without a file says how to give one.
    #[test]
    fn rerun_save_with_a_space_is_read_as_save_equals() {
        let joined = |args: &[&str]| -> Vec<String> {
            rerun_save_joined(args.iter().map(std::ffi::OsString::from))
                .into_iter()
                .map(|a| a.to_string_lossy().into_owned())
                .collect()
        };
        assert_eq!(
            joined(&["pma-exo", "single", "--rerun", "save", "x.rrd", "--json"]),
            ["pma-exo", "single", "--rerun", "save=x.rrd", "--json"]
        );
        assert_eq!(
            joined(&["pma-exo", "single", "--rerun=save", "x.rrd"]),
            ["pma-exo", "single", "--rerun", "save=x.rrd"]
        );
        assert_eq!(
            joined(&["pma-exo", "simulate", "--rerun", "spawn", "gait_spastic"]),
            ["pma-exo", "simulate", "--rerun", "spawn", "gait_spastic"]
        );
        let e = Cli::try_parse_from(joined(&["pma-exo", "single", "--rerun", "save"]))
            .err()
            .expect("no file");
        assert!(
            cli_error_line(&e.to_string()).contains("--rerun save=PATH.rrd"),
            "{e}"
        );
    }

    #[test]
    fn clap_errors_keep_their_content_on_one_line() {
        let e = Cli::try_parse_from(["pma-exo", "tune"])
            .err()
            .expect("missing argument");
        let line = cli_error_line(&e.to_string());
        assert!(
            line.contains("--controller <aprc-ndo|aprc|psmc|ndo-smc|sta|pid>"),
            "{line}"
        );
        assert!(!line.contains('\n'));
        let e = Cli::try_parse_from(["pma-exo", "single", "--reference", "square"])
            .err()
            .expect("bad value");
        let line = cli_error_line(&e.to_string());
        assert!(
            line.contains("square") && line.contains("sine") && line.contains("chirp"),
            "{line}"
        );
        let e = Cli::try_parse_from(["pma-exo", "single", "--reference", "sin"])
            .err()
            .expect("bad value");
        let line = cli_error_line(&e.to_string());
        assert!(line.contains("sine"), "{line}");
    }
}
