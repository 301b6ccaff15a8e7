//! `pma-exo identify`: a plant file from a rig log.
use crate::output::{self, OutFile};
use crate::say;
use anyhow::{bail, Context, Result};
use pma_studies::identify::identify_logs;
use std::path::PathBuf;

/// `identify`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The rig log (`rig excite --out`, or any `rig run` log); with an unweighed load, two
    /// logs of the same muscle, the second with a known mass added (`rig excite
    /// --added-mass-kg`).
    #[arg(required = true, num_args = 1..=8)]
    logs: Vec<PathBuf>,
    /// The plant file to write (takes `single --plant`, `tune --plant`, `[virtual] plant`).
    #[arg(long)]
    out: PathBuf,
    /// The load the muscle lifted, weighed (kg); default the log's `[load] mass_kg`, else
    /// identified from the added-mass logs.
    #[arg(long, allow_negative_numbers = true)]
    load_kg: Option<f64>,
    /// Lowest held-out fit (%) for which the plant file is written.
    #[arg(long, default_value_t = MIN_FIT_PERCENT, allow_negative_numbers = true)]
    min_fit: f64,
    /// Write the plant file even if the held-out fit is below `--min-fit`, and read logs
    /// that fail the checks `rig replay` makes (no digest line: cut short; edited rows;
    /// periods missing). A plant other commands would refuse is never written.
    #[arg(long)]
    force: bool,
    /// Seed of the bootstrap.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

/// The lowest held-out fit (%) an identified model must reach by default (`identify` and
/// `rig commission`'s `--min-fit`).
pub const MIN_FIT_PERCENT: f64 = 90.0;

/// A `--min-fit` that is a percentage.
pub fn check_min_fit(percent: f64) -> Result<()> {
    if !(percent.is_finite() && (0.0..=100.0).contains(&percent)) {
        bail!("--min-fit {percent} must be 0 to 100 (%)");
    }
    Ok(())
}

/// Runs `identify`.
pub fn run(a: Args) -> Result<i32> {
    if let Some(m) = a.load_kg {
        if !(m.is_finite() && (0.05..=pma_model::MAX_LOAD_KG).contains(&m)) {
            anyhow::bail!("--load-kg = {m} is invalid: must be 0.05 to 600 kg");
        }
    }
    let inputs: Vec<(&str, &std::path::Path)> =
        a.logs.iter().map(|l| ("log", l.as_path())).collect();
    output::refuse_input_as_output(&inputs, &[("--out", &a.out)])?;
    check_min_fit(a.min_fit)?;
    // Every log checked before any is fitted.
    let logs = a
        .logs
        .iter()
        .map(|l| pma_exo::setup::load_id_log(l, a.force))
        .collect::<Result<Vec<_>>>()?;
    // The operator's stop before the output exists: a signal never leaves its `.part`.
    let stop = output::stop_flag()?;
    let out = OutFile::create(&a.out)?;
    let load_kg = a.load_kg.or(logs[0].weighed_kg);
    let id = match identify_logs(&logs, load_kg, a.seed, &stop) {
        Err(pma_studies::StudyError::Interrupted) => {
            eprintln!(
                "interrupted by the operator: `{}` was not written",
                a.out.display()
            );
            return Ok(output::INTERRUPTED);
        }
        r => r?,
    };
    if id.fit_percent < a.min_fit && !a.force {
        bail!(
            "the identified model fits the held-out quarter of the log at {:.1} % only (--min-fit {}): nothing written (--force writes it anyway)",
            id.fit_percent,
            a.min_fit
        );
    }
    let plant = id.plant_config(&logs[0]);
    // Even with --force: a plant file `single --plant` would refuse is not a result.
    plant.validate().with_context(|| {
        format!(
            "the identified plant is outside what the simulator accepts: `{}` not written",
            a.out.display()
        )
    })?;
    let names: Vec<String> = a.logs.iter().map(|l| l.display().to_string()).collect();
    let load = load_kg.map_or(String::new(), |m| format!(" --load-kg {m}"));
    let text = format!(
        "# Identified by `pma-exo identify {}{load}` ({} simulations)\n# {}\n{}",
        names.join(" "),
        id.simulations,
        id.force_scale,
        toml::to_string(&plant).context("cannot serialise the plant")?
    );
    out.finish_with(&text)?;
    if a.json {
        let provenance = crate::provenance::Provenance {
            plant: Some(format!("identified into {}", a.out.display())),
            seeds: crate::provenance::Seeds::of("bootstrap", a.seed),
            ..crate::provenance::Provenance::of_this_run()
        };
        say!("{}", provenance.attach(&id)?);
        return Ok(0);
    }
    say!(
        "identified from {:.0} s: valve {:.1} ms + {:.1} ms dead time ({}), load {:.3} kg ({}), held-out fit {:.2} % ({:.1} um RMS), residual {:.1} um RMS (sensor noise {:.1} um); wrote {}",
        id.log_s,
        id.valve_time_constant_s * 1e3,
        id.valve_dead_time_s * 1e3,
        id.valve_source,
        id.load_mass_kg,
        id.load_source,
        id.fit_percent,
        id.rms_error_m * 1e6,
        id.residual_rms_m * 1e6,
        id.noise_rms_m * 1e6,
        a.out.display()
    );
    for (name, e) in &id.parameters {
        say!(
            "  {name:<24} {:>10.4} [{:.4}, {:.4}]",
            e.value,
            e.low,
            e.high
        );
    }
    say!(
        "  condition number {:.3e}; {}",
        id.condition_number,
        id.force_scale
    );
    if let Some(r) = id.restart_s {
        say!("  fitted restarting from the measured state every {r} s (open loop, the model's error dwarfed the noise); held out open loop");
    }
    for (p, q, rho) in &id.inseparable {
        say!("  not separable: {p} and {q} (correlation {rho:.3})");
    }
    Ok(0)
}
