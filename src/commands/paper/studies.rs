//! The studies `paper` adds to the paper's experiments, run as the shipped sweeps
//! (`crates/pma-studies/models/sweeps/`): shocks, Fig. 9 (added loads) and a Monte Carlo population.
use anyhow::{bail, Result};
use std::sync::atomic::{AtomicBool, Ordering};

/// A study stopped by SIGINT or SIGTERM.
#[derive(Debug, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;
use pma_studies::shock::{BLOCK_S, BLOCK_START_S, IMPACT_START_S, JUMP_DOWN_S, JUMP_UP_S};
use pma_studies::sweep::{self, Shard, Summary, Sweep};
use std::path::Path;

/// What the studies produced.
pub struct Studies {
    /// `(results.json key, summary)`.
    pub summaries: Vec<(&'static str, Summary)>,
    /// The report's sections.
    pub report: String,
    /// PNGs written.
    pub plots: usize,
}

/// Runs one shipped sweep into `out/sweeps/<name>` (resuming what is there).
fn run_sweep(name: &str, out: &Path, stop: &AtomicBool) -> Result<(Sweep, Summary, sweep::Runs)> {
    let s = sweep::load(name)?;
    let sweeps = out.join("sweeps");
    crate::output::create_dir(&sweeps)?;
    let dir = sweeps.join(name);
    let bar = crate::output::progress_bar(s.jobs.len() as u64, &format!("runs of `{name}`"));
    let progress = |done: usize| bar.set_position(done as u64);
    let executed = crate::commands::sweep::execute(&s, &dir, Shard::default(), &progress, stop);
    bar.finish_and_clear();
    executed?;
    if stop.load(Ordering::Relaxed) {
        bail!(Interrupted);
    }
    let (manifest, runs, missing) = sweep::merge(std::slice::from_ref(&dir))?;
    let summary = sweep::summarise(&manifest.name, &runs, missing.len());
    // The paper's figures come from every run: a failed one (now or recorded before) is an
    // error here, not a gap in a table.
    if let Some(f) = summary.failed_runs.first() {
        bail!(
            "run {} of the shipped sweep `{name}` ({}) failed: {} (in `{}`)",
            f.run,
            f.ran,
            f.failed,
            dir.display()
        );
    }
    Ok((s, summary, runs))
}

/// Markdown of a sweep's summary as a section of the report (headings one level down).
fn section(title: &str, intro: &str, summary: &Summary) -> String {
    let md = sweep::markdown(summary)
        .lines()
        .skip(1)
        .map(|l| {
            if l.starts_with('#') {
                format!("#{l}")
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    format!("\n## {title}\n\n{intro}\n{md}\n")
}

/// The shocks' figures: one PNG per plant and experiment, every run of it.
fn shock_plots(s: &Sweep, out: &Path) -> Result<usize> {
    let mut n = 0;
    let experiments = [
        (
            "jump",
            "none",
            "Reference jump 5 -> 25 mm at 4 s, back at 10 s",
            (3.5, 13.5),
            vec![
                (JUMP_UP_S, "up".to_owned()),
                (JUMP_DOWN_S, "down".to_owned()),
            ],
        ),
        (
            "sine",
            "block",
            "Load held by an obstacle from 8 s, released at 9 s",
            (7.5, 12.5),
            vec![
                (BLOCK_START_S, "block".to_owned()),
                (BLOCK_START_S + BLOCK_S, "release".to_owned()),
            ],
        ),
        (
            "sine",
            "impact-up",
            "150 N lifting the load for 30 ms at 8.5 s",
            (8.0, 11.5),
            vec![(IMPACT_START_S, "impact".to_owned())],
        ),
        (
            "sine",
            "impact-down",
            "150 N pushing the load down for 30 ms at 8.5 s",
            (8.0, 11.5),
            vec![(IMPACT_START_S, "impact".to_owned())],
        ),
    ];
    for plant in ["mismatch", "realistic"] {
        for (reference, event, title, window, marks) in &experiments {
            let mut traces = Vec::new();
            for p in s.bench_points() {
                let (_, name, _) = p.resolve_plant()?;
                if name == plant && p.reference.name() == *reference && p.event.name() == *event {
                    traces.push(p.trace(s.file.duration_s, s.file.period_s, *window, 2)?);
                }
            }
            let path = out.join(format!("shock_{event}_{plant}.png").replace("none", "jump"));
            let subtitle = format!("{plant} plant; every controller at equal activity (3 bar/s), APRC-NDO also with the paper's gains and m_p 0.5-15");
            crate::output::write_via_temp(&path, |tmp| {
                super::figures::shock(tmp, title, &subtitle, &traces, marks)
            })?;
            n += 1;
        }
    }
    Ok(n)
}

/// Fig. 9: the tracking error of every controller on the chirp, one panel per added load
/// (rows) and gain set (columns).
fn fig9_plot(s: &Sweep, out: &Path) -> Result<usize> {
    let mut cells: Vec<(String, Vec<sweep::Trace>)> = Vec::new();
    for p in s.bench_points() {
        let (_, plant, _) = p.resolve_plant()?;
        let caption = format!("{plant}, {} gains", p.gains);
        let mut trace = p.trace(
            s.file.duration_s,
            s.file.period_s,
            (0.0, s.file.duration_s),
            10,
        )?;
        trace.label = p.controller.to_string();
        match cells.iter_mut().find(|(c, _)| *c == caption) {
            Some((_, runs)) => runs.push(trace),
            None => cells.push((caption, vec![trace])),
        }
    }
    let (default, equal): (Vec<_>, Vec<_>) =
        cells.into_iter().partition(|(c, _)| c.contains("default"));
    let cells: Vec<_> = default
        .into_iter()
        .zip(equal)
        .flat_map(|(a, b)| [a, b])
        .collect();
    let path = out.join("fig9.png");
    crate::output::write_via_temp(&path, |tmp| {
        super::figures::error_grid(
            tmp,
            "Fig. 9: the chirp (0.1 -> 0.5 Hz) with loads added, gains unchanged",
            "mismatch plant (2.5 kg; the controllers assume 2 kg) + 0, 2.5, 5 kg; left: default gains (the paper's for APRC(-NDO)), right: equal activity (3 bar/s)",
            &cells,
            2,
        )
    })?;
    Ok(1)
}

/// Runs the three studies, writes their plots, and returns their summaries and sections.
pub fn run_all(out: &Path, stop: &AtomicBool) -> Result<Studies> {
    let (shocks, shock_summary, _) = run_sweep("shocks", out, stop)?;
    let mut plots = shock_plots(&shocks, out)?;
    let (fig9_sweep, fig9, _) = run_sweep("fig9", out, stop)?;
    plots += fig9_plot(&fig9_sweep, out)?;
    let (_, mc, mc_runs) = run_sweep("monte_carlo", out, stop)?;
    let png = out.join("robustness.png");
    crate::output::write_via_temp(&png, |tmp| {
        crate::plot::rte_distributions(tmp, "monte_carlo", &mc_runs)
    })?;
    plots += 1;
    let mut report = String::new();
    report.push_str(&section(
        "Not in the paper: shocks",
        "`crates/pma-studies/models/sweeps/shocks.toml` (14 s per run): the reference jumps 5 -> 25 mm at 4 s and back at 10 s; on the sine, an obstacle holds the load from 8 s to 9 s; or 150 N for 30 ms at 8.5 s, up or down. Every controller at equal activity (3 bar/s), APRC-NDO also with the paper's gains and m_p in {0.5, 1, 5, 15}; plants `mismatch` and `realistic`. Plots: `shock_<event>_<plant>.png`.",
        &shock_summary,
    ));
    report.push_str(&section(
        "Fig. 9: the chirp with added loads",
        "`crates/pma-studies/models/sweeps/fig9.toml`: 0, 2.5 and 5 kg added to the `mismatch` load (2.5 kg), gains unchanged (the controllers assume 2 kg). Plot: `fig9.png` (tracking errors over time, per load and gain set).",
        &fig9,
    ));
    report.push_str(&section(
        "Not in the paper: robustness over 200 plants",
        "`crates/pma-studies/models/sweeps/monte_carlo.toml`: every Table I parameter independently within +-20 %, load 1-5 kg, valve lag 0-30 ms, sensor noise 0-20 um RMS; equal-activity (3 bar/s) gains. Plot: `robustness.png`.",
        &mc,
    ));
    Ok(Studies {
        summaries: vec![
            ("shocks", shock_summary),
            ("fig9", fig9),
            ("robustness", mc),
        ],
        report,
        plots,
    })
}
