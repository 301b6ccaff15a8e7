//! What a sweep's output directory holds, and the parallel runner: shards, the manifest
//! (`sweep.json`), the runs' lines (`runs.jsonl`, a torn last line found on resume),
//! the runs still to do, and merging. The files themselves are written by the caller
//! (the binary's one output path: modes, atomic replacement, the directory's lock).
use super::{FailedRecord, Job, Record, Sweep};
use crate::files::{dir_error, read_error, write_error};
use crate::StudyError;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
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

/// The complete lines of a `runs.jsonl`, by run index, and where a torn last line (from a
/// kill) starts, if `tolerate_torn_end` (the caller cuts it off so that its run is redone;
/// otherwise it is an error). Only indices below `runs_in_sweep` belong to the sweep; a
/// run recorded twice must be recorded the same way (runs are deterministic: two different
/// lines for one run mean two different sweeps wrote here).
pub fn read_runs(
    path: &Path,
    tolerate_torn_end: bool,
    runs_in_sweep: usize,
) -> Result<RunsFile, StudyError> {
    let mut runs = BTreeMap::new();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(RunsFile {
                runs,
                torn_at: None,
            })
        }
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
            _ if offset == text.len() && tolerate_torn_end => break,
            _ => {
                return Err(dir_error(
                    path,
                    format!("line {} is not a run record", number + 1),
                ))
            }
        }
    }
    Ok(RunsFile {
        runs,
        torn_at: (good_bytes < text.len()).then_some(good_bytes as u64),
    })
}

/// What a `runs.jsonl` holds.
#[derive(Debug, Clone, Default)]
pub struct RunsFile {
    /// Its runs by index.
    pub runs: Runs,
    /// Where a torn last line starts (bytes), if there is one.
    pub torn_at: Option<u64>,
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

/// The manifest of this shard of `sweep`.
pub fn manifest(sweep: &Sweep, shard: Shard) -> Manifest {
    Manifest {
        name: sweep.file.name.clone(),
        fingerprint: sweep.fingerprint.clone(),
        runs: sweep.jobs.len(),
        shard,
    }
}

/// Checks that the manifest `text` read from `path` is `manifest`: a directory holds one
/// shard of one sweep.
pub fn check_manifest(path: &Path, text: &str, manifest: &Manifest) -> Result<(), StudyError> {
    let found: Manifest = serde_json::from_str(text).map_err(|e| dir_error(path, e))?;
    if &found != manifest {
        return Err(dir_error(
            path,
            format!(
                "this directory holds shard {} of sweep `{}` ({}), not shard {} of `{}` ({}): use another --out",
                found.shard, found.name, found.fingerprint, manifest.shard, manifest.name, manifest.fingerprint
            ),
        ));
    }
    Ok(())
}

/// The runs of `shard` not in `done` (read from `path`), after checking that each run in
/// `done` is the sweep's run of its index.
pub fn to_do<'s>(
    sweep: &'s Sweep,
    shard: Shard,
    done: &Runs,
    path: &Path,
) -> Result<Vec<&'s Job>, StudyError> {
    for r in done.values() {
        check_record(path, r, &sweep.jobs[r.run()])?;
    }
    Ok(sweep
        .jobs
        .iter()
        .filter(|j| shard.contains(j.index()) && !done.contains_key(&j.index()))
        .collect())
}

/// Runs `jobs` on the current rayon pool, handing each run's record to `record` (from
/// any thread, as the runs end); returns how many ran. A run that fails is recorded as
/// failed ([`FailedRecord`]) and the others go on. Once `stop` is raised no new run
/// starts. The first error of `record` ends the runs and is returned.
pub fn run_jobs<E: Send>(
    sweep: &Sweep,
    jobs: &[&Job],
    stop: &std::sync::atomic::AtomicBool,
    record: &(dyn Fn(&Record) -> Result<(), E> + Sync),
) -> Result<usize, E> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let ran = AtomicUsize::new(0);
    jobs.par_iter().try_for_each(|job| {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let r = job
            .run(&sweep.file)
            .unwrap_or_else(|e| Record::Failed(FailedRecord::of(job, &e)));
        record(&r)?;
        ran.fetch_add(1, Ordering::Relaxed);
        Ok(())
    })?;
    Ok(ran.into_inner())
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
        for (index, r) in read_runs(&path, false, m.runs)?.runs {
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

/// The text of a `runs.jsonl` of `runs`, sorted by index (`path` names it in errors).
pub fn runs_jsonl(path: &Path, runs: &Runs) -> Result<String, StudyError> {
    let mut text = String::new();
    for r in runs.values() {
        text.push_str(&serde_json::to_string(r).map_err(|e| write_error(path, e))?);
        text.push('\n');
    }
    Ok(text)
}
