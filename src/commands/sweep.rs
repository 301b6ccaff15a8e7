//! `pma-exo sweep`: grids of bench or leg runs in parallel, sharded, resumable; `sweep
//! merge`.
use crate::output;
use crate::say;
use anyhow::{bail, Context, Result};
use pma_studies::sweep::{self, FailedRecord, Record, Shard, Sweep};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

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
    let progress = |done: usize| bar.set_position(done as u64);
    let start = std::time::Instant::now();
    let exec = super::with_threads(a.threads, || {
        execute(&sweep, &out, a.shard, &progress, &stop)
    })??;
    bar.finish_and_clear();
    warn_failed(&file, &exec.failed_now);
    if stop.load(Ordering::Relaxed) {
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

/// How an execution went.
pub struct Execution {
    /// Runs of this shard already in the directory (resumed).
    pub already_done: usize,
    /// Run now.
    pub run_now: usize,
    /// The runs that failed now (recorded, and not run again by a resume).
    pub failed_now: Vec<FailedRecord>,
}

/// Runs this shard of `sweep` into `out` (`runs.jsonl`, `sweep.json`; the directory is
/// created, one level) on the current rayon pool, skipping the runs already written there;
/// `progress(done)` is called after each run. The directory is locked for the run. Once
/// `stop` is raised no new run starts (the runs written stay; the same command resumes).
pub fn execute(
    sweep: &Sweep,
    out: &Path,
    shard: Shard,
    progress: &(dyn Fn(usize) + Sync),
    stop: &AtomicBool,
) -> Result<Execution> {
    output::create_dir(out)?;
    let _lock = output::DirLock::take(
        out,
        "another `pma-exo sweep` is writing into this directory: wait for it or use another --out",
    )?;
    let manifest = sweep::manifest(sweep, shard);
    let manifest_path = out.join("sweep.json");
    match std::fs::read_to_string(&manifest_path) {
        Ok(text) => sweep::check_manifest(&manifest_path, &text, &manifest)?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            output::write_file(&manifest_path, &serde_json::to_string_pretty(&manifest)?)?;
        }
        Err(e) => {
            return Err(e).with_context(|| format!("cannot read `{}`", manifest_path.display()))
        }
    }
    let runs_path = out.join("runs.jsonl");
    let found = sweep::read_runs(&runs_path, true, sweep.jobs.len())?;
    let todo = sweep::to_do(sweep, shard, &found.runs, &runs_path)?;
    let selected = sweep
        .jobs
        .iter()
        .filter(|j| shard.contains(j.index()))
        .count();
    let file = output::AppendFile::open(&runs_path, found.torn_at)?;
    let failed_now = std::sync::Mutex::new(Vec::new());
    let done = AtomicUsize::new(0);
    let record = |r: &Record| -> Result<()> {
        file.line(&serde_json::to_string(r)?)?;
        if let Record::Failed(f) = r {
            failed_now
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(f.clone());
        }
        progress(done.fetch_add(1, Ordering::Relaxed) + 1);
        Ok(())
    };
    let run_now = sweep::run_jobs(sweep, &todo, stop, &record)?;
    let mut failed_now = failed_now.into_inner().unwrap_or_else(|e| e.into_inner());
    failed_now.sort_by_key(|f| f.run);
    Ok(Execution {
        already_done: selected - todo.len(),
        run_now,
        failed_now,
    })
}

/// One line on stderr per run that failed now: the run, what it ran, why, and the sweep.
fn warn_failed(file: &str, failed: &[FailedRecord]) {
    for f in failed {
        eprintln!(
            "warning: sweep `{file}`: run {} ({}) failed, recorded as failed (a resume does not run it again): {}",
            f.run, f.ran, f.failed
        );
    }
}

fn merge(dirs: &[PathBuf], out: &Path) -> Result<i32> {
    let inputs: Vec<(&str, &Path)> = dirs
        .iter()
        .map(|d| ("shard directory", d.as_path()))
        .collect();
    output::refuse_input_as_output(&inputs, &[("--out", out)])?;
    // The inputs are read and checked before anything is written: missing runs or shards
    // leave no --out.
    let (manifest, runs, missing) = sweep::merge(dirs)?;
    if !missing.is_empty() {
        bail!(
            "{} of {} runs are missing (first: run {}): merge every shard (nothing written)",
            missing.len(),
            manifest.runs,
            missing[0]
        );
    }
    output::create_dir(out)?;
    let runs_path = out.join("runs.jsonl");
    output::write_file(&runs_path, &sweep::runs_jsonl(&runs_path, &runs)?)?;
    let merged = pma_studies::sweep::Manifest {
        shard: Shard::default(),
        ..manifest
    };
    output::write_file(
        &out.join("sweep.json"),
        &serde_json::to_string_pretty(&merged)?,
    )?;
    summarise_dirs(&[out.to_path_buf()], out)?;
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
    let mut notes = Vec::new();
    if summary.failed > 0 {
        notes.push(format!("{} failed", summary.failed));
    }
    if !missing.is_empty() {
        notes.push(format!("{} missing", missing.len()));
    }
    say!(
        "sweep `{}`: {} runs in {} groups{}; wrote {}",
        summary.name,
        summary.runs,
        summary.groups.len() + summary.leg_groups.len(),
        if notes.is_empty() {
            String::new()
        } else {
            format!(" ({})", notes.join(", "))
        },
        written.join(", ")
    );
    Ok(())
}
