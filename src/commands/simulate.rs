//! `pma-exo simulate`: the gait-training simulation of the exoskeleton leg.
use super::{viz, RerunArgs};
use crate::output::{self, CsvOut, INTERRUPTED};
use crate::say;
use anyhow::{bail, Result};
use pma_leg::{LegOutput, LegPlant, LegReport, LegSample, LegSim, Scenario};
use pma_loop::{Period, Recorder};
use std::path::PathBuf;

/// Estimated wall time of one leg period (release build, with margin).
pub const LEG_PERIOD_S: f64 = 20e-6;

/// `simulate`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// gait_training (default), gait_realistic, or a scenario .toml file.
    #[arg(default_value = "gait_training")]
    scenario: String,
    /// Simulated seconds (default: the scenario's); at least two strides.
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Stream the time series (joints, and per muscle the states Rerun logs) to CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
    #[command(flatten)]
    rerun: RerunArgs,
}

impl Default for Args {
    /// `pma-exo` without a subcommand: the default scenario.
    fn default() -> Self {
        Self {
            scenario: "gait_training".into(),
            duration: None,
            csv: None,
            json: false,
            yes: false,
            rerun: RerunArgs::default(),
        }
    }
}

/// Per-muscle CSV columns (after `<muscle>_`), the series Rerun logs.
pub const MUSCLE_COLUMNS: [&str; 10] = [
    "pressure_cmd_pa",
    "pressure_pa",
    "length_ref_m",
    "length_m",
    "force_n",
    "proxy_m",
    "s_p",
    "s_q",
    "gain_hat",
    "disturbance_hat",
];

/// The CSV header for the leg's muscles.
pub fn csv_header(muscles: &[String]) -> Vec<String> {
    let mut h: Vec<String> = ["t_s", "hip_ref_deg", "hip_deg", "knee_ref_deg", "knee_deg"]
        .iter()
        .map(|c| (*c).to_owned())
        .collect();
    for m in muscles {
        h.extend(MUSCLE_COLUMNS.iter().map(|c| format!("{m}_{c}")));
    }
    h
}

/// Streams each period to the CSV file (one reused row buffer, no allocation).
struct CsvRecorder {
    out: CsvOut,
    row: Vec<f64>,
}

impl Recorder<LegPlant, LegOutput> for CsvRecorder {
    fn record(&mut self, p: &Period<'_, LegPlant, LegOutput>) {
        let s = LegSample::of(p);
        self.row.clear();
        self.row.push(s.t_s);
        for j in 0..2 {
            self.row.push(s.reference_rad[j].to_degrees());
            self.row.push(s.angle_rad[j].to_degrees());
        }
        for i in 0..4 {
            let d = &s.diagnostics[i];
            self.row.extend_from_slice(&[
                s.pressure_cmd_pa[i],
                s.pressure_pa[i],
                s.length_ref_m[i],
                s.length_m[i],
                s.force_n[i],
                d.proxy_position_m,
                d.s_p,
                d.s_q,
                d.gain_hat,
                d.disturbance_hat,
            ]);
        }
        self.out.row(&self.row);
    }
}

/// Advances the progress bar every 1 % of the run.
struct Progress {
    bar: indicatif::ProgressBar,
    every: u64,
}

impl<B: pma_loop::Backend, O> Recorder<B, O> for Progress {
    fn record(&mut self, p: &Period<'_, B, O>) {
        if p.index.is_multiple_of(self.every) {
            self.bar.set_position(p.index);
        }
    }
}

/// Runs `simulate`.
pub fn run(a: Args) -> Result<i32> {
    let loaded = Scenario::load(&a.scenario)?;
    let sc = &loaded.scenario;
    let duration = a.duration.unwrap_or(sc.duration_s);
    super::check_duration(duration)?;
    let two_strides = 2.0 * sc.gait.stride_period_s;
    if duration < two_strides {
        bail!(
            "a simulation of {duration} s is shorter than two strides ({two_strides} s): its tracking figures start after the first stride"
        );
    }
    let mut sim = LegSim::new(&loaded)?;
    let settings = sim.settings(duration)?;
    output::check_wall_time(
        "this simulation",
        settings.periods() as f64,
        LEG_PERIOD_S,
        a.yes,
    )?;
    let names: Vec<String> = sim
        .muscles()
        .iter()
        .map(|m| m.geometry.name.clone())
        .collect();
    let csv = match &a.csv {
        Some(p) => Some(CsvRecorder {
            out: CsvOut::create(p, &csv_header(&names))?,
            row: Vec::with_capacity(5 + 4 * MUSCLE_COLUMNS.len()),
        }),
        None => None,
    };
    let meta = format!(
        "# {}\n\n{}\n\ngait `{}` at a {} s stride; co-contraction {} bar; APRC-NDO gains:\n\n```\n{:#?}\n```\n",
        sc.name,
        sc.description,
        sc.gait.speed,
        sc.gait.stride_period_s,
        sc.control.cocontraction_pa / 1e5,
        sc.control.gains
    );
    let viz = viz::leg(&a.rerun, &sim, &meta)?;
    let bar = output::progress_bar(settings.periods(), "periods");
    let progress = Progress {
        bar: bar.clone(),
        every: (settings.periods() / 100).max(1),
    };
    let stop = output::stop_flag()?;
    let settings = settings.with_stop_flag(&stop);
    let mut recorders = (csv, viz, progress);
    let report = sim.run_with(&settings, &mut recorders);
    bar.finish_and_clear();
    let report = report?;
    let (csv, viz, _) = recorders;
    if let Some(c) = csv {
        c.out.finish()?;
    }
    // The results are printed even if the viewer failed; its error comes after them.
    let viz_result = viz::finish(viz);
    if !report.finite {
        bail!(
            "the simulation went non-finite (scenario {})",
            report.scenario
        );
    }
    if a.json {
        say!("{}", serde_json::to_string(&report)?);
    } else {
        print_summary(&report)?;
    }
    viz_result?;
    if report.interrupted {
        eprintln!(
            "interrupted after {} s: the figures and the CSV cover the run so far",
            report.duration_s
        );
        return Ok(INTERRUPTED);
    }
    Ok(0)
}

fn print_summary(r: &LegReport) -> Result<()> {
    say!(
        "{} ({} s simulated, {:.0}x real time)",
        r.scenario,
        r.duration_s,
        r.real_time_factor
    );
    for (name, j) in &r.joints {
        say!(
            "  {name:5} tracking error after the first stride: RMS {:.3} deg, max {:.3} deg",
            j.rms_deg,
            j.max_deg
        );
    }
    for (name, m) in &r.muscles {
        say!(
            "  {name:13} pressure {:.2}..{:.2} bar, slack {:.3} s",
            m.p_min_pa / 1e5,
            m.p_max_pa / 1e5,
            m.slack_s
        );
    }
    say!(
        "  co-contraction (mean pressure): {:.3} bar in the second stride, {:.3} bar in the last; command variation {:.1} bar/s",
        r.cocontraction_pa.start / 1e5,
        r.cocontraction_pa.end / 1e5,
        r.command_variation_bar_per_s
    );
    Ok(())
}
