//! `pma-exo simulate`: the gait-training simulation of the exoskeleton leg.
use anyhow::{bail, Context, Result};
use pma_leg::{LegOutput, LegPlant, LegReport, LegSample, LegSim, Scenario};
use pma_loop::{FnRecorder, Period};
use std::io::{IsTerminal, Write};
use std::path::Path;

/// Runs a scenario (embedded name or `.toml` path) and prints a summary or JSON.
pub fn run(
    scenario: &str,
    duration: Option<f64>,
    csv: Option<&Path>,
    json: bool,
    sink: &pma_viz::Sink,
    rerun_hz: Option<f64>,
) -> Result<()> {
    let loaded = Scenario::load(scenario)?;
    let duration = duration.unwrap_or(loaded.scenario.duration_s);
    if !(duration.is_finite() && duration > 0.0) {
        bail!("--duration must be a finite number of seconds > 0 (got {duration})");
    }
    let mut sim = LegSim::new(&loaded)?;
    let steps = (duration / loaded.scenario.period_s).round() as usize;
    let mut viz = pma_exo::viz::open(sink, "pma-exo simulate", loaded.scenario.period_s, rerun_hz)?;
    if let Some(v) = viz.as_mut() {
        let sc = &loaded.scenario;
        let meta = format!(
            "# {}\n\n{}\n\ngait `{}` at a {} s stride; co-contraction {} bar; APRC-NDO gains:\n\n```\n{:#?}\n```\n",
            sc.name,
            sc.description,
            sc.gait.speed,
            sc.gait.stride_period_s,
            sc.control.cocontraction_pa / 1e5,
            sc.control.gains
        );
        pma_exo::viz::leg_layout(v, &sim, &meta)?;
    }
    let mut samples: Vec<LegSample> = Vec::with_capacity(if csv.is_some() { steps } else { 0 });
    let (mut step, mut scalars, mut viz_error) = (0i64, [0.0; pma_exo::viz::LEG_SCALARS], None);
    let show_progress = duration > 5.0 && std::io::stderr().is_terminal();
    let every = (steps / 100).max(1);
    let mut record = FnRecorder(|p: &Period<'_, LegPlant, LegOutput>| {
        step += 1;
        let s = LegSample::of(p);
        if csv.is_some() {
            samples.push(s);
        }
        if let Some(v) = viz.as_mut() {
            if let Err(e) = pma_exo::viz::push_leg(v, p.backend, &s, step, &mut scalars) {
                viz_error.get_or_insert(e);
            }
        }
        if show_progress && (step as usize).is_multiple_of(every) {
            let f = step as f64 / steps as f64;
            let done = (f * 40.0).round() as usize;
            eprint!(
                "\r[{}{}] {:3.0} %",
                "=".repeat(done),
                " ".repeat(40 - done.min(40)),
                f * 100.0
            );
        }
    });
    let report = sim.run(duration, &mut record)?;
    if let Some(e) = viz_error {
        return Err(e);
    }
    pma_exo::viz::finish(viz)?;
    if show_progress {
        eprintln!("\r[{}] 100 %", "=".repeat(40));
    }
    if let Some(path) = csv {
        write_csv(path, &sim, &samples)?;
    }
    if !report.finite {
        bail!(
            "the simulation went non-finite (scenario {})",
            report.scenario
        );
    }
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_summary(&report);
    }
    Ok(())
}

fn print_summary(r: &LegReport) {
    println!(
        "{} ({} s simulated, {:.0}x real time)",
        r.scenario, r.duration_s, r.real_time_factor
    );
    for (name, j) in &r.joints {
        println!(
            "  {name:5} tracking error after the first stride: RMS {:.3} deg, max {:.3} deg",
            j.rms_deg, j.max_deg
        );
    }
    for (name, m) in &r.muscles {
        println!(
            "  {name:13} pressure {:.2}..{:.2} bar, slack {:.3} s",
            m.p_min_pa / 1e5,
            m.p_max_pa / 1e5,
            m.slack_s
        );
    }
    println!(
        "  co-contraction (mean pressure): {:.3} bar in the second stride, {:.3} bar in the last; command variation {:.1} bar/s",
        r.cocontraction_pa.start / 1e5,
        r.cocontraction_pa.end / 1e5,
        r.command_variation_bar_per_s
    );
}

fn write_csv(path: &Path, sim: &LegSim, samples: &[LegSample]) -> Result<()> {
    let file = std::fs::File::create(path)
        .with_context(|| format!("cannot create `{}`", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    write!(w, "t_s,hip_ref_deg,hip_deg,knee_ref_deg,knee_deg")?;
    for m in sim.muscles() {
        let n = &m.geometry.name;
        write!(
            w,
            ",{n}_pressure_cmd_pa,{n}_pressure_pa,{n}_length_ref_m,{n}_length_m,{n}_force_n"
        )?;
    }
    writeln!(w)?;
    for s in samples {
        write!(
            w,
            "{},{},{},{},{}",
            s.t_s,
            s.reference_rad[0].to_degrees(),
            s.angle_rad[0].to_degrees(),
            s.reference_rad[1].to_degrees(),
            s.angle_rad[1].to_degrees()
        )?;
        for i in 0..4 {
            write!(
                w,
                ",{},{},{},{},{}",
                s.pressure_cmd_pa[i],
                s.pressure_pa[i],
                s.length_ref_m[i],
                s.length_m[i],
                s.force_n[i]
            )?;
        }
        writeln!(w)?;
    }
    w.flush()
        .with_context(|| format!("cannot write `{}`", path.display()))?;
    Ok(())
}
