//! `pma-exo pendulum`: the Wartenberg pendulum test on the leg's patient model.
mod figure;
use super::{viz, RunOutput, SampleCsv};
use crate::output;
use crate::provenance::{Provenance, Seeds};
use crate::say;
use anyhow::Result;
use pma_exo::setup::{PendulumArgs, PendulumRun, Spasticity};
use pma_loop::Period;
use pma_studies::pendulum::{self, PendulumReport, PendulumSample};
use std::path::PathBuf;

/// `pendulum`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// The scenario whose leg and patient are tested (embedded name or .toml file).
    #[arg(default_value = "gait_training")]
    scenario: String,
    /// Knee flexion at release (deg); 0 is full extension, the classic test.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    knee_deg: f64,
    /// Hip flexion, held (deg); the pelvis is pitched so that the thigh lies horizontal.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    hip_deg: f64,
    /// Simulated seconds.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    duration: f64,
    /// Replace the scenario's spasticity at hip and knee by this preset.
    #[arg(long, value_enum)]
    spasticity: Option<Spasticity>,
    /// Draw the test into this directory (`pendulum.png`: the knee with R2's construction,
    /// the patient's knee torque).
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    output: RunOutput,
}

/// Runs `pendulum`.
pub fn run(a: Args) -> Result<i32> {
    let run = PendulumRun::load(&PendulumArgs {
        scenario: &a.scenario,
        knee_deg: a.knee_deg,
        hip_deg: a.hip_deg,
        duration_s: a.duration,
        spasticity: a.spasticity,
    })?;
    let (loaded, setup) = (&run.loaded, run.setup);
    let plot_file = a.plot.as_ref().map(|dir| dir.join("pendulum.png"));
    let mut outputs = a.output.files();
    if let Some(png) = &plot_file {
        outputs.push(("--plot", png));
    }
    output::refuse_input_as_output(&super::scenario_inputs(&a.scenario, loaded, None), &outputs)?;
    let provenance = Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &loaded.scenario.name)),
        controller: Some("none (muscles vented and unhooked)".into()),
        patient: Some(match a.spasticity {
            Some(s) => format!("spasticity {} at hip and knee", s.name()),
            None => super::simulate::patient_name(loaded),
        }),
        seeds: Seeds::of_scenario(&loaded.scenario),
        ..Provenance::of_this_run()
    };
    let (sim, settings) = run.seated()?;
    let damping = run.knee_damping_nm_s_per_rad();
    let csv = a
        .output
        .csv
        .as_deref()
        .map(|p| {
            SampleCsv::create(
                p,
                &PendulumSample::schema(),
                move |p: &Period<'_, _, _>| PendulumSample::of(p, damping),
                &provenance,
            )
        })
        .transpose()?;
    let meta = format!(
        "# Pendulum test: {}\n\n{}\n\n{}\n\nthigh horizontal, hip held at {} deg, knee released from {} deg; muscles vented and unhooked.\n",
        loaded.scenario.name,
        loaded.scenario.description,
        provenance.line(),
        a.hip_deg,
        a.knee_deg
    );
    let viz = viz::pendulum(&a.output.rerun, &sim, &meta, damping)?;
    let stop = output::stop_flag()?;
    let settings = settings.with_stop_flag(&stop);
    if let Some(dir) = &a.plot {
        output::create_dir(dir)?;
    }
    let periods = (a.duration / loaded.scenario.period_s) as u64;
    let trace = a
        .plot
        .as_ref()
        .map(|_| super::simulate::Trace::with_capacity(periods, 1));
    let mut recorders = (csv, viz, trace);
    let report = pendulum::run(sim, setup, &settings, &mut recorders)?;
    let (csv, viz, trace) = recorders;
    if let (Some(path), Some(trace)) = (&plot_file, trace) {
        let marks = figure::PendulumMarks {
            start_deg: report.knee_start_deg,
            first_peak_deg: report.first_peak_deg,
            rest_deg: report.knee_rest_deg,
            r2: report.r2,
        };
        crate::plot::register_font()?;
        let title = format!(
            "Pendulum test: {}",
            provenance.patient.as_deref().unwrap_or("-")
        );
        output::write_via_temp(path, |tmp| {
            figure::pendulum_run(tmp, &title, &provenance.command, &trace.0[0], &marks)
        })?;
        output::wrote(path);
    }
    let non_finite =
        (!report.finite).then(|| format!("the pendulum test (scenario {})", report.scenario));
    super::conclude(
        (csv, viz),
        &report,
        &provenance,
        non_finite,
        a.output.json,
        print_summary,
    )?;
    if !report.settled {
        eprintln!(
            "warning: the knee still moved {:.1} deg in the last second: no resting angle, so no R2; run longer (--duration)",
            report.last_second_range_deg
        );
    }
    Ok(0)
}

fn print_summary(r: &PendulumReport) -> Result<()> {
    say!(
        "pendulum test, {} ({} s; thigh horizontal, hip held at {:.1} deg, pelvis pitched {:.1} deg)",
        r.scenario,
        r.duration_s,
        r.hip_deg,
        r.pelvis_pitch_deg
    );
    say!(
        "  knee released at {:.1} deg, first flexion peak {:.1} deg (excursion {:.1} deg), rest {:.1} deg",
        r.knee_start_deg,
        r.first_peak_deg,
        r.first_swing_excursion_deg,
        r.knee_rest_deg
    );
    let r2 = match (r.r2, r.r2n) {
        (Some(r2), Some(r2n)) => {
            format!("R2 {r2:.3} (R2n {r2n:.3}; healthy adults 1.678 +- 0.090)")
        }
        _ => "R2 not computed (the knee has not come to rest)".to_owned(),
    };
    say!(
        "  {r2}, {} oscillations, peak knee speed {:.0} deg/s",
        r.oscillations,
        r.peak_knee_velocity_deg_s
    );
    say!(
        "  peak patient torque {:.2} N m; knee still moving {:.2} deg in the last second",
        r.peak_patient_torque_nm,
        r.last_second_range_deg
    );
    Ok(())
}
