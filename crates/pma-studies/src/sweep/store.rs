//! A sweep's output directory: shards, the manifest (`sweep.json`), the runs' lines
//! (`runs.jsonl`, appended one write per line, a torn last line cut off on resume), the
//! lock that keeps two sweeps out of one directory, the parallel runner, and merging.
use super::{Job, Record, Sweep};
use crate::files::{dir_error, read_error, write_atomically, write_error};
use crate::StudyError;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};

/// index is `I - 1` modulo `N`, so that every part gets a share of every grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// Which part, from 1.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Default for Shard {
    fn default() -> Self {
        Self { index: 1, count: 1 }
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("`{s}` is not a shard: expected I/N with 1 <= I <= N (e.g. 2/8)");
        let (i, n) = s.split_once('/').ok_or_else(err)?;
        let (index, count): (usize, usize) =
            (i.parse().map_err(|_| err())?, n.parse().map_err(|_| err())?);
        if index == 0 || count == 0 || index > count {
            return Err(err());
        }
        Ok(Self { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Whether run `index` belongs to this part.
    pub fn contains(&self, index: usize) -> bool {
        index % self.count == self.index - 1
    }
}

/// What an output directory says it holds (`sweep.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Sweep name.
    pub name: String,
    /// Fingerprint of the sweep file.
    pub fingerprint: String,
    /// Runs in the whole sweep.
    pub runs: usize,
    /// This directory's part.
    pub shard: Shard,
}

/// The complete lines of a `runs.jsonl` (a torn last line, from a kill, is cut off the
/// file so that it is redone), by run index. Only indices below `runs_in_sweep` belong to
/// the sweep; a run recorded twice must be recorded the same way (runs are
/// deterministic: two different lines for one run mean two different sweeps wrote here).
pub fn read_runs(path: &Path, repair: bool, runs_in_sweep: usize) -> Result<Runs, StudyError> {
    let mut runs = BTreeMap::new();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(runs),
        Err(e) => return Err(read_error(path, e)),
    };
    let mut good_bytes = 0usize;
    let mut offset = 0usize;
    for (number, line) in text.split_inclusive('\n').enumerate() {
        offset += line.len();
        let complete = line.ends_with('\n');
        match serde_json::from_str::<Record>(line.trim_end()) {
            Ok(r) if complete => {
                add_run(
                    path,
                    &format!("line {}", number + 1),
                    r,
                    runs_in_sweep,
                    &mut runs,
                )?;
                good_bytes = offset;
            }
            _ if offset == text.len() && repair => break,
            _ => {
                return Err(dir_error(
                    path,
                    format!("line {} is not a run record", number + 1),
                ))
            }
        }
    }
    if repair && good_bytes < text.len() {
        let f = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| write_error(path, e))?;
        f.set_len(good_bytes as u64)
            .map_err(|e| write_error(path, e))?;
    }
    Ok(runs)
}

fn add_run(
    path: &Path,
    at: &str,
    r: Record,
    runs_in_sweep: usize,
    runs: &mut Runs,
) -> Result<(), StudyError> {
    if r.run() >= runs_in_sweep {
        return Err(dir_error(
            path,
            format!(
                "{at} records run {}, but the sweep has runs 0..{}: not a record of this sweep",
                r.run(),
                runs_in_sweep.saturating_sub(1)
            ),
        ));
    }
    match runs.get(&r.run()) {
        Some(seen) if *seen != r => Err(dir_error(
            path,
            format!(
                "{at} records run {} differently from an earlier record: two sweeps wrote here",
                r.run()
            ),
        )),
        Some(_) => Ok(()),
        None => {
            runs.insert(r.run(), r);
            Ok(())
        }
    }
}

/// Holds a directory for one sweep at a time (an advisory lock on `DIR/.lock`, released
/// when the process ends, even by a kill).
pub struct DirLock(#[allow(dead_code)] std::fs::File);

impl DirLock {
    /// Takes the lock of `out`, or fails at once if another process holds it.
    pub fn take(out: &Path) -> Result<Self, StudyError> {
        let path = out.join(".lock");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| write_error(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(Self(file)),
            Err(std::fs::TryLockError::WouldBlock) => Err(dir_error(
                out,
                "another `pma-exo sweep` is writing into this directory: wait for it or use another --out",
            )),
            Err(std::fs::TryLockError::Error(e)) => Err(write_error(&path, e)),
        }
    }
}

/// How an execution went.
#[derive(Debug, Clone, PartialEq)]
pub struct Execution {
    /// Runs of this shard.
    pub selected: usize,
    /// Of which already in the file (resumed).
    pub already_done: usize,
    /// Run now.
    pub run_now: usize,
}

/// Runs this shard of `sweep` into `out` (`runs.jsonl`, `sweep.json`), on the current
/// rayon pool, skipping the runs already written there; `progress(done, total)` is called
/// after each run. Once `stop` is raised no new run starts (the runs written stay; the
/// same command resumes).
pub fn execute(
    sweep: &Sweep,
    out: &Path,
    shard: Shard,
    progress: &(dyn Fn(usize, usize) + Sync),
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Execution, StudyError> {
    use rayon::prelude::*;
    std::fs::create_dir_all(out).map_err(|e| write_error(out, e))?;
    let manifest = Manifest {
        name: sweep.file.name.clone(),
        fingerprint: sweep.fingerprint.clone(),
        runs: sweep.jobs.len(),
        shard,
    };
    let _lock = DirLock::take(out)?;
    check_manifest(out, &manifest)?;
    let runs_path = out.join("runs.jsonl");
    let done = read_runs(&runs_path, true, sweep.jobs.len())?;
    for r in done.values() {
        check_record(&runs_path, r, &sweep.jobs[r.run()])?;
    }
    let todo: Vec<&Job> = sweep
        .jobs
        .iter()
        .filter(|j| shard.contains(j.index()) && !done.contains_key(&j.index()))
        .collect();
    let selected = sweep
        .jobs
        .iter()
        .filter(|j| shard.contains(j.index()))
        .count();
    let file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&runs_path)
        .map_err(|e| write_error(&runs_path, e))?;
    let writer = std::sync::Mutex::new(file);
    let counter = std::sync::atomic::AtomicUsize::new(0);
    let total = todo.len();
    todo.par_iter()
        .try_for_each(|job| -> Result<(), StudyError> {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                return Ok(());
            }
            let record = job.run(&sweep.file)?;
            let mut line =
                serde_json::to_string(&record).map_err(|e| write_error(&runs_path, e))?;
            line.push('\n');
            {
                let mut f = writer.lock().unwrap_or_else(|e| e.into_inner());
                // One write per line: a kill tears at most the line being written.
                f.write_all(line.as_bytes())
                    .map_err(|e| write_error(&runs_path, e))?;
            }
            let n = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, total);
            Ok(())
        })?;
    Ok(Execution {
        selected,
        already_done: selected - total,
        run_now: counter.into_inner(),
    })
}

fn check_manifest(out: &Path, manifest: &Manifest) -> Result<(), StudyError> {
    let path = out.join("sweep.json");
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let found: Manifest = serde_json::from_str(&text).map_err(|e| dir_error(&path, e))?;
            if &found != manifest {
                return Err(dir_error(
                    &path,
                    format!(
                        "this directory holds shard {} of sweep `{}` ({}), not shard {} of `{}` ({}): use another --out",
                        found.shard, found.name, found.fingerprint, manifest.shard, manifest.name, manifest.fingerprint
                    ),
                ));
            }
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let text = serde_json::to_string_pretty(manifest).map_err(|e| write_error(&path, e))?;
            write_atomically(&path, &text)
        }
        Err(e) => Err(read_error(&path, e)),
    }
}

/// A recorded run must be the sweep's run of that index (the same controller, gains and
/// setting): a record from another sweep is refused.
fn check_record(path: &Path, r: &Record, job: &Job) -> Result<(), StudyError> {
    let (recorded, expected) = (r.describe(), job.describe());
    if recorded == expected {
        Ok(())
    } else {
        Err(dir_error(
            path,
            format!(
                "run {} is recorded as {recorded}, but the sweep's run {} is {expected}: not a record of this sweep",
                r.run(),
                job.index()
            ),
        ))
    }
}

/// Runs by index.
pub type Runs = BTreeMap<usize, Record>;

/// Joins the shards in `dirs` (one sweep, any shards): their runs by index, checked
/// for coming from the same sweep file; the indices still missing are reported.
pub fn merge(dirs: &[PathBuf]) -> Result<(Manifest, Runs, Vec<usize>), StudyError> {
    let mut first: Option<Manifest> = None;
    let mut runs = BTreeMap::new();
    let mut shards = BTreeSet::new();
    for dir in dirs {
        let path = dir.join("sweep.json");
        let text = std::fs::read_to_string(&path).map_err(|e| read_error(&path, e))?;
        let m: Manifest = serde_json::from_str(&text).map_err(|e| dir_error(&path, e))?;
        if let Some(f) = &first {
            if f.fingerprint != m.fingerprint || f.runs != m.runs {
                return Err(dir_error(
                    &path,
                    format!(
                        "holds sweep `{}` ({}), not `{}` ({})",
                        m.name, m.fingerprint, f.name, f.fingerprint
                    ),
                ));
            }
        }
        shards.insert(m.shard.index);
        let path = dir.join("runs.jsonl");
        for (index, r) in read_runs(&path, false, m.runs)? {
            add_run(&path, &format!("run {index}"), r, m.runs, &mut runs)?;
        }
        first.get_or_insert(m);
    }
    let manifest = first.ok_or_else(|| dir_error(Path::new("."), "no directory to merge"))?;
    let missing: Vec<usize> = (0..manifest.runs)
        .filter(|i| !runs.contains_key(i))
        .collect();
    Ok((manifest, runs, missing))
}

/// Writes `runs.jsonl` sorted by index.
pub fn write_runs(path: &Path, runs: &Runs) -> Result<(), StudyError> {
    let mut text = String::new();
    for r in runs.values() {
        text.push_str(&serde_json::to_string(r).map_err(|e| write_error(path, e))?);
        text.push('\n');
    }
    write_atomically(path, &text)
}
