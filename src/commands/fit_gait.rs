//! `pma-exo fit-gait`: a treadmill scenario's hip reference made consistent with its belt.
use crate::output::{self, OutFile, INTERRUPTED};
use crate::provenance::Provenance;
use crate::say;
use anyhow::Result;
use pma_exo::setup::{BeltArg, BodySpeedArg};
use pma_leg::gait::{FourierSeries, HARMONICS};
use pma_leg::{fit_gait, GaitFit, GaitFitSettings, GaitFitStep, Scenario};
use std::path::PathBuf;
use std::sync::atomic::Ordering;

/// `fit-gait`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// An embedded treadmill scenario (gait_treadmill, gait_treadmill_spastic,
    /// gait_treadmill_unsupported, gait_treadmill_one_leg) or a scenario .toml file with a
    /// [treadmill].
    #[arg(default_value = "gait_treadmill")]
    scenario: String,
    /// Servo-driven runs after the first (each about 1 s here).
    #[arg(long, default_value_t = 15)]
    iterations: usize,
    /// Share of the measured speed error corrected per run (0-1].
    #[arg(long, default_value_t = 0.8, allow_negative_numbers = true)]
    gain: f64,
    /// Strides measured per run.
    #[arg(long, default_value_t = 3)]
    strides: usize,
    /// The body's fore-aft speed the stance is fitted to: `constant` (the pelvis stands
    /// still over the belt) or `normative` (it swings as the adults' does, from their
    /// fore-aft ground reaction).
    #[arg(long, default_value = "constant", value_name = "constant|normative")]
    body_speed: BodySpeedArg,
    /// How the belt's speed is set on the fitted hip: `no-drag` (secant runs to where the
    /// harness carries no mean fore-aft force, as for a person walking steadily on the
    /// belt) or `stance` (the stance contact's mean speed, the hip's own fit rule).
    #[arg(long, default_value = "no-drag", value_name = "no-drag|stance")]
    belt: BeltArg,
    /// Where to write the `[gait.hip_correction]` and the belt speed for the scenario
    /// (nothing is written without it).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the fit as JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `fit-gait`.
pub fn run(a: Args) -> Result<i32> {
    let settings = GaitFitSettings {
        iterations: a.iterations,
        gain: a.gain,
        strides: a.strides,
        body_speed: a.body_speed.into(),
        belt: a.belt.into(),
    };
    settings.validate().map_err(|e| anyhow::anyhow!("--{e}"))?;
    let loaded = Scenario::load(&a.scenario)?;
    if let Some(out) = &a.out {
        output::refuse_input_as_output(
            &super::scenario_inputs(&a.scenario, &loaded, None),
            &[("--out", out)],
        )?;
    }
    let out_file = a.out.as_deref().map(OutFile::create).transpose()?;
    let stop = output::stop_flag()?;
    let fit = fit_gait(&loaded, &settings, || stop.load(Ordering::Relaxed))?;
    if stop.load(Ordering::Relaxed) {
        eprintln!("interrupted by the operator: nothing written");
        return Ok(INTERRUPTED);
    }
    let provenance = Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &loaded.scenario.name)),
        ..Provenance::of_this_run()
    };
    let snippet = scenario_snippet(&fit, &provenance.command);
    if a.json {
        let mut json = pma_exo::setup::fit_figures(&fit);
        json.insert("provenance".into(), serde_json::to_value(&provenance)?);
        say!("{}", serde_json::to_string(&json)?);
    } else {
        print_steps(&fit)?;
        say!("{snippet}");
        say!("{}", provenance.line());
    }
    warn_if_the_stance_does_not_walk(&fit);
    if let (Some(out_file), Some(path)) = (out_file, a.out.as_deref()) {
        out_file.finish_with(&snippet)?;
        output::wrote(path);
    }
    Ok(0)
}

/// A belt without drag far from the stance's speed: the stance slides instead of walking.
fn warn_if_the_stance_does_not_walk(fit: &GaitFit) {
    if let Some(off) = fit.belt_off_stance() {
        if off.abs() > pma_leg::tools::BELT_OFF_STANCE_WARN {
            eprintln!(
                "note: the belt without drag, {:.4} m/s, is {:+.1} % from the stance's speed: the stance does not move with the belt (its feet slide; docs/treadmill.md, at 0 % support)",
                fit.belt_speed_m_s,
                100.0 * off
            );
        }
    }
}

fn print_steps(fit: &GaitFit) -> Result<()> {
    say!("the hip's fit:");
    print_table(&fit.steps, |s| s.iteration == fit.best)?;
    if !fit.belt_steps.is_empty() {
        say!("the belt on the kept hip, to no mean harness force:");
        print_table(&fit.belt_steps, |s| s.belt_speed_m_s == fit.belt_speed_m_s)?;
    }
    Ok(())
}

fn print_table(steps: &[GaitFitStep], kept: impl Fn(&GaitFitStep) -> bool) -> Result<()> {
    say!("run  belt (m/s)  contact speed error RMS (m/s)  peak demand hip / knee (N m/kg)  slip per stride (mm)  GRF peak / belt load  harness mean (N)");
    for s in steps {
        let mark = if kept(s) { "  <- kept" } else { "" };
        say!(
            "{:3}  {:10.4}  {:29.4}  {:14.2} / {:5.2}  {:19.1}  {:20.3}  {:16.1}{mark}",
            s.iteration,
            s.belt_speed_m_s,
            s.contact_speed_error_rms_m_s,
            s.peak_demand_nm_kg[0],
            s.peak_demand_nm_kg[1],
            1000.0 * s.slip_per_stride_m,
            s.grf_peak_over_belt_load,
            s.harness_fore_aft_mean_n
        );
    }
    Ok(())
}

/// The lines to put into the scenario.
fn scenario_snippet(fit: &GaitFit, command: &str) -> String {
    let list = |v: &[f64; HARMONICS + 1]| {
        v.iter()
            .map(|c| format!("{c:.5}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let FourierSeries { cos_deg, sin_deg } = &fit.hip_correction;
    let belt = if fit.belt_steps.is_empty() {
        String::new()
    } else {
        format!(
            ", the belt where the harness carries no mean fore-aft force ({} belt runs)",
            fit.belt_steps.len()
        )
    };
    format!(
        "# The hip's stance made consistent with the belt: `{command}` (run {} of {}{belt}).\n[gait.hip_correction]\ncos_deg = [{}]\nsin_deg = [{}]\n\n# and in [treadmill]:\nspeed_m_per_s = {:.4}\n",
        fit.best,
        fit.steps.len() - 1,
        list(cos_deg),
        list(sin_deg),
        fit.belt_speed_m_s
    )
}
