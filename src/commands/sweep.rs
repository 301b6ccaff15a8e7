//! `pma-exo sweep`: grids of bench or leg runs in parallel, sharded, resumable; `sweep
//! merge`.
use crate::output;
use crate::say;
use anyhow::{bail, Context, Result};
use pma_studies::sweep::{self, Shard};
use std::path::{Path, PathBuf};

/// `sweep`'s arguments.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    #[command(subcommand)]
    merge: Option<MergeCommand>,
    /// A sweep file, or a shipped one: shocks, fig9, monte_carlo, leg_patients.
    #[arg(required = true)]
    file: Option<String>,
    /// Output directory (runs.jsonl, sweep.json; summary.json and summary.md when the
    /// whole sweep is there). Run again with the same --out to resume.
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Run only part I of N (1-based), e.g. for a cluster job array.
    #[arg(long, default_value = "1/1", value_name = "I/N")]
    shard: Shard,
    /// Worker threads (default: one per core); the results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Run even if it would take over an hour.
    #[arg(long)]
    yes: bool,
}

#[derive(clap::Subcommand)]
enum MergeCommand {
    /// Join shards (the output directories of one sweep) and summarise them.
    Merge {
        /// The shards' output directories.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Where the merged runs.jsonl and the summary go.
        #[arg(long, default_value = "sweep-merged")]
        out: PathBuf,
    },
}

/// Runs `sweep`.
pub fn run(a: Args) -> Result<i32> {
    if let Some(MergeCommand::Merge { dirs, out }) = a.merge {
        return merge(&dirs, &out);
    }
    let (Some(file), Some(out)) = (a.file, a.out) else {
        bail!("a sweep file and --out are required (or `sweep merge DIR...`)");
    };
    let sweep = sweep::load(&file)?;
    let selected: Vec<&sweep::Job> = sweep
        .jobs
        .iter()
        .filter(|j| a.shard.contains(j.index()))
        .collect();
    // The estimate in bench periods (1 us each), whatever the runs are.
    let bench_periods: f64 = selected
        .iter()
        .map(|j| {
            let (periods, cost_s) = j.periods(&sweep.file);
            periods * cost_s / 1e-6
        })
        .sum();
    let selected = selected.len();
    // More threads than cores do not make a sweep faster.
    let cores = rayon::current_num_threads().max(1);
    let threads = a.threads.unwrap_or(cores).clamp(1, cores);
    output::check_wall_time("this sweep", bench_periods, 1e-6 / threads as f64, a.yes)?;
    let stop = output::stop_flag()?;
    let bar = output::progress_bar(selected as u64, "runs");
    let progress = |done: usize, _total: usize| bar.set_position(done as u64);
    let start = std::time::Instant::now();
    let exec = super::with_threads(a.threads, || {
        sweep::execute(&sweep, &out, a.shard, &progress, &stop)
    })??;
    bar.finish_and_clear();
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        eprintln!(
            "interrupted: {} runs written now, {} before, in `{}`; run the same command again to resume",
            exec.run_now,
            exec.already_done,
            out.display()
        );
        return Ok(output::INTERRUPTED);
    }
    let wall = start.elapsed().as_secs_f64();
    eprintln!(
        "sweep `{}` shard {}: {} runs now ({:.1} runs/s), {} already in `{}`",
        sweep.file.name,
        a.shard,
        exec.run_now,
        exec.run_now as f64 / wall.max(1e-9),
        exec.already_done,
        out.display()
    );
    if a.shard == Shard::default() {
        summarise_dirs(std::slice::from_ref(&out), &out)?;
    }
    Ok(0)
}

fn merge(dirs: &[PathBuf], out: &Path) -> Result<i32> {
    // The inputs are read before anything is created: a missing shard leaves no empty --out.
    let (manifest, runs, missing) = sweep::merge(dirs)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create `{}`", out.display()))?;
    sweep::write_runs(&out.join("runs.jsonl"), &runs)?;
    let merged = pma_studies::sweep::Manifest {
        shard: Shard::default(),
        ..manifest
    };
    output::write_file(
        &out.join("sweep.json"),
        &serde_json::to_string_pretty(&merged)?,
    )?;
    summarise_dirs(&[out.to_path_buf()], out)?;
    if !missing.is_empty() {
        bail!(
            "{} of {} runs are missing (first: run {}): merge every shard",
            missing.len(),
            merged.runs,
            missing[0]
        );
    }
    Ok(0)
}

/// Writes `summary.json`, `summary.md`, and `rte.png` (bench runs) and `leg_rms.png`
/// (leg runs) of the runs in `dirs` into `out`.
fn summarise_dirs(dirs: &[PathBuf], out: &Path) -> Result<()> {
    let (manifest, runs, missing) = sweep::merge(dirs)?;
    let summary = sweep::summarise(&manifest.name, &runs, missing.len());
    let json = out.join("summary.json");
    output::write_file(&json, &serde_json::to_string_pretty(&summary)?)?;
    let md = out.join("summary.md");
    output::write_file(&md, &sweep::markdown(&summary))?;
    let mut written = vec![json.display().to_string(), md.display().to_string()];
    crate::plot::register_font()?;
    type Plot = fn(&Path, &str, &sweep::Runs) -> crate::plot::DrawResult;
    let plots: [(&str, bool, Plot); 2] = [
        (
            "rte.png",
            !summary.groups.is_empty(),
            crate::plot::rte_distributions,
        ),
        (
            "leg_rms.png",
            !summary.leg_groups.is_empty(),
            crate::plot::leg_rms_distributions,
        ),
    ];
    for (file, wanted, plot) in plots {
        if wanted {
            let png = out.join(file);
            output::write_via_temp(&png, |tmp| plot(tmp, &summary.name, &runs))?;
            written.push(png.display().to_string());
        }
    }
    say!(
        "sweep `{}`: {} runs in {} groups{}; wrote {}",
        summary.name,
        summary.runs,
        summary.groups.len() + summary.leg_groups.len(),
        if missing.is_empty() {
            String::new()
        } else {
            format!(" ({} missing)", missing.len())
        },
        written.join(", ")
    );
    Ok(())
}
