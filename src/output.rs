//! What the commands write: stdout that a closed pipe ends quietly, output files opened
//! (and named in every error) before a run starts, CSV streamed row by row, a progress
//! bar with an ETA, a refusal of runs that would take hours, and Ctrl-C.
//!
//! Every file a command writes goes through here: results written beside their path and
//! renamed onto it when complete ([`OutFile`], [`CsvOut`], [`write_file`], [`StagedPath`]
//! for libraries that write by path: plots, Rerun recordings), a sweep's growing
//! `runs.jsonl` ([`AppendFile`]) and its lock ([`DirLock`]), output directories
//! ([`create_dir`]). A new file gets the mode the umask gives (`0666 & !umask`, as any
//! program's), a replaced file keeps its own; no output may be an input or another output
//! of the same command ([`refuse_input_as_output`]).
use anyhow::{bail, Context, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Stdout was closed by its reader (`pma-exo simulate | head -1`): the program ends
/// quietly, with status 0.
#[derive(Debug, thiserror::Error)]
#[error("stdout closed")]
pub struct StdoutClosed;

/// Writes one line to stdout.
pub fn line(args: std::fmt::Arguments) -> Result<()> {
    let mut out = std::io::stdout().lock();
    let r = out
        .write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush());
    match r {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        r => r.context("cannot write to stdout"),
    }
}

/// `println!` that ends quietly on a closed pipe instead of panicking.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::output::line(format_args!($($arg)*))?
    };
}

/// Where an output's bytes go until it is complete.
enum Staged {
    /// A temporary file beside the file it will replace (same directory, so that the final
    /// rename is atomic), named `.NAME.XXXXXX.part`.
    Temp {
        temp: tempfile::NamedTempFile,
        path: PathBuf,
        /// The mode of the file it replaces (set on the temporary file when it is
        /// renamed, so that a writer reopening it by path can still write it).
        replaced: Option<std::fs::Permissions>,
    },
    /// Straight into something that is not a regular file (`/dev/stdout`, a pipe,
    /// `/dev/null`): it holds no earlier result to protect, and renaming over it would
    /// replace the device itself.
    Direct(std::fs::File),
}

impl Staged {
    /// Prepares `path` (`keep_extension`: the temporary name ends in the target's
    /// extension, for writers that choose the format by it). A symbolic link is followed:
    /// its target is replaced, not the link.
    fn new(path: &Path, keep_extension: bool) -> Result<Self> {
        let context = || format!("cannot create `{}`", path.display());
        // Found now, not at the rename after the run: a path ending in `/` names a
        // directory, never the file the output is.
        if path
            .as_os_str()
            .to_string_lossy()
            .ends_with(std::path::MAIN_SEPARATOR)
        {
            bail!(
                "cannot create `{}`: a file's path cannot end in `{}`",
                path.display(),
                std::path::MAIN_SEPARATOR
            );
        }
        let (path, replaced) = match std::fs::metadata(path) {
            Ok(meta) if !meta.is_file() => {
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .with_context(context)?;
                return Ok(Staged::Direct(file));
            }
            Ok(meta) => (
                std::fs::canonicalize(path).with_context(context)?,
                Some(meta.permissions()),
            ),
            Err(_) => (path.to_path_buf(), None),
        };
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path.file_name().with_context(context)?.to_string_lossy();
        let suffix = match path.extension() {
            Some(ext) if keep_extension => format!(".{}", ext.to_string_lossy()),
            _ => ".part".to_owned(),
        };
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(&suffix);
        #[cfg(unix)]
        builder.permissions(new_file_permissions());
        let temp = builder.tempfile_in(dir).with_context(context)?;
        Ok(Staged::Temp {
            temp,
            path,
            replaced,
        })
    }

    /// The path a writer that opens files itself (plotters) writes to.
    fn write_path(&self, target: &Path) -> PathBuf {
        match self {
            Staged::Temp { temp, .. } => temp.path().to_path_buf(),
            Staged::Direct(_) => target.to_path_buf(),
        }
    }

    /// The output is complete: renamed onto its path (an earlier file there is replaced
    /// only now, never truncated before the work is done).
    fn commit(self, shown: &Path) -> Result<()> {
        let context = || format!("cannot write `{}`", shown.display());
        match self {
            Staged::Temp {
                temp,
                path,
                replaced,
            } => {
                if let Some(mode) = replaced {
                    temp.as_file().set_permissions(mode).with_context(context)?;
                }
                temp.as_file().sync_all().with_context(context)?;
                temp.persist(&path)
                    .map(drop)
                    .map_err(|e| anyhow::Error::new(e.error))
                    .with_context(context)
            }
            Staged::Direct(mut f) => f.flush().with_context(context),
        }
    }
}

impl Write for Staged {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Staged::Temp { temp, .. } => temp.write(buf),
            Staged::Direct(f) => f.write(buf),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Staged::Temp { temp, .. } => temp.flush(),
            Staged::Direct(f) => f.flush(),
        }
    }
}

/// The mode of a new file: what `open(2)` gives `0666` under the process's umask (a
/// temporary file is otherwise created `0600`, and colleagues could not read the results).
#[cfg(unix)]
fn new_file_permissions() -> std::fs::Permissions {
    use std::os::unix::fs::PermissionsExt;
    std::fs::Permissions::from_mode(0o666)
}

/// An output that another library writes by its path (plotters, Rerun's file sink): a
/// temporary file beside `path`, with `path`'s extension, to write to, renamed onto `path`
/// by [`StagedPath::commit`]. Dropped uncommitted (the run failed), it is removed and the
/// previous file at `path` stays as it was.
pub struct StagedPath {
    staged: Staged,
    path: PathBuf,
}

impl StagedPath {
    /// Prepares `path`: a temporary file beside it, now (a bad path fails before any work).
    pub fn create(path: &Path) -> Result<Self> {
        Ok(Self {
            staged: Staged::new(path, true)?,
            path: path.to_path_buf(),
        })
    }

    /// The path it is for.
    // Only the Rerun recorder asks (`commands::viz`), which a build without it leaves out.
    #[cfg_attr(not(feature = "rerun"), allow(dead_code))]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Where the writer writes until the commit.
    pub fn write_path(&self) -> PathBuf {
        self.staged.write_path(&self.path)
    }

    /// The output is complete: renamed onto its path.
    pub fn commit(self) -> Result<()> {
        self.staged.commit(&self.path)
    }
}

/// Draws or writes a file through `write(path to write)` and renames it onto `path` when
/// `write` succeeds (plots: plotters writes the file itself, by its extension).
pub fn write_via_temp<E: std::fmt::Display>(
    path: &Path,
    write: impl FnOnce(&Path) -> std::result::Result<(), E>,
) -> Result<()> {
    stage(path, write)?.commit()
}

/// [`write_via_temp`] without the rename: the file written beside `path`, to be committed
/// with the command's other outputs ([`StagedPath::commit`] on each once all are written,
/// so that a command whose second file fails leaves the first as it was too).
pub fn stage<E: std::fmt::Display>(
    path: &Path,
    write: impl FnOnce(&Path) -> std::result::Result<(), E>,
) -> Result<StagedPath> {
    let staged = StagedPath::create(path)?;
    write(&staged.write_path())
        .map_err(|e| anyhow::anyhow!("cannot write `{}`: {}", path.display(), plain(&e)))?;
    Ok(staged)
}

/// A writer's error as one plain line: the operating system's message where a drawing
/// library wraps it in its debug form (`backend error: Drawing backend error:
/// ImageError(IoError(Custom { .., error: "No space left on device (os error 28)" }))`).
fn plain(e: &impl std::fmt::Display) -> String {
    let text = e.to_string();
    text.find("error: \"")
        .map(|start| &text[start + 8..])
        .and_then(|rest| rest.find('"').map(|end| rest[..end].to_owned()))
        .unwrap_or(text)
}

/// Says on stderr that `path` was written (every output file of a command is named once).
pub fn wrote(path: &Path) {
    eprintln!("wrote {}", path.display());
}

/// Creates the output directory `dir` if it does not exist: one level, in an existing
/// parent (a mistyped parent is an error, not a new tree of directories).
pub fn create_dir(dir: &Path) -> Result<()> {
    if dir.is_dir() {
        return Ok(());
    }
    if dir.exists() {
        bail!(
            "`{}` exists and is not a directory: give a directory for the outputs",
            dir.display()
        );
    }
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        bail!(
            "cannot create `{}`: its parent `{}` is not a directory (one directory level is created; create the parent first)",
            dir.display(),
            parent.display()
        );
    }
    std::fs::create_dir(dir).with_context(|| format!("cannot create `{}`", dir.display()))
}

/// A result file written in full or not at all: it is created now as a temporary file
/// beside `path` (so that a bad path fails before any work) and renamed onto `path` only by
/// [`OutFile::finish_with`]. An interrupted or failed run leaves the previous file intact.
pub struct OutFile {
    path: PathBuf,
    file: BufWriter<Staged>,
}

impl OutFile {
    /// Prepares `path`: a temporary file beside it, now.
    pub fn create(path: &Path) -> Result<Self> {
        Ok(Self {
            path: path.to_path_buf(),
            file: BufWriter::new(Staged::new(path, false)?),
        })
    }

    /// Writes `text` and renames the file onto its path.
    pub fn finish_with(mut self, text: &str) -> Result<()> {
        let context = || format!("cannot write `{}`", self.path.display());
        self.file
            .write_all(text.as_bytes())
            .and_then(|()| self.file.flush())
            .with_context(context)?;
        let staged = self
            .file
            .into_inner()
            .map_err(|e| anyhow::Error::new(e.into_error()))
            .with_context(context)?;
        staged.commit(&self.path)
    }
}

/// Writes `text` to `path` in full or not at all (through a temporary file).
pub fn write_file(path: &Path, text: &str) -> Result<()> {
    OutFile::create(path)?.finish_with(text)
}

/// A CSV file streamed row by row through a buffer into a temporary file beside its path,
/// renamed onto the path by [`CsvOut::finish`] (also after Ctrl-C: the rows so far are a
/// complete CSV). The first I/O error is kept (with the path) and reported by `finish`;
/// later rows are dropped.
pub struct CsvOut {
    path: PathBuf,
    /// `None` only after a write that lost it, with `error` set.
    writer: Option<csv::Writer<BufWriter<Staged>>>,
    error: Option<anyhow::Error>,
    rows: u64,
}

impl CsvOut {
    /// Prepares `path` and writes the header now, after `comment` as a `# ` line if given.
    pub fn create(path: &Path, header: &[String], comment: Option<&str>) -> Result<Self> {
        let staged = Staged::new(path, false)?;
        let mut out = BufWriter::with_capacity(1 << 16, staged);
        if let Some(c) = comment {
            use std::io::Write;
            writeln!(out, "# {c}").with_context(|| format!("cannot write `{}`", path.display()))?;
        }
        let mut writer = csv::Writer::from_writer(out);
        writer
            .write_record(header)
            .with_context(|| format!("cannot write `{}`", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            writer: Some(writer),
            error: None,
            rows: 0,
        })
    }

    /// The path it is for.
    // Only the Rerun recorder asks (`commands::viz`), which a build without it leaves out.
    #[cfg_attr(not(feature = "rerun"), allow(dead_code))]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// One row of numbers.
    pub fn row(&mut self, values: &[f64]) {
        if self.error.is_some() {
            return;
        }
        let Some(writer) = &mut self.writer else {
            return;
        };
        if let Err(e) = writer.serialize(values) {
            self.error = Some(
                anyhow::Error::new(e).context(format!("cannot write `{}`", self.path.display())),
            );
        } else {
            self.rows += 1;
        }
    }

    /// A `# ` line after the rows so far (how a run ended: a collapse the trainer stopped).
    pub fn comment(&mut self, text: &str) {
        if self.error.is_some() {
            return;
        }
        // The csv writer holds the file: one more record of a single field, its text made
        // a comment by its first character (commas and quotes kept out, so that it is not
        // quoted), in a writer that accepts a record of another length.
        let line: String = format!("# {text}")
            .chars()
            .map(|c| if c == ',' || c == '"' { ';' } else { c })
            .collect();
        let Some(taken) = self.writer.take() else {
            return;
        };
        let r = match taken.into_inner() {
            Ok(inner) => {
                let mut flexible = csv::WriterBuilder::new()
                    .flexible(true)
                    .has_headers(false)
                    .from_writer(inner);
                let r = flexible.write_record([line.as_str()]);
                self.writer = Some(flexible);
                r.map_err(anyhow::Error::new)
            }
            Err(e) => Err(anyhow::Error::new(e.into_error())),
        };
        if let Err(e) = r {
            self.error = Some(e.context(format!("cannot write `{}`", self.path.display())));
        }
    }

    /// Flushes and renames the file onto its path; the first error of the run, if any,
    /// naming the file (the previous file at the path is then left as it was).
    pub fn finish(mut self) -> Result<u64> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let context = || format!("cannot write `{}`", self.path.display());
        let Some(writer) = self.writer.take() else {
            anyhow::bail!("cannot write `{}`", self.path.display());
        };
        let staged = writer
            .into_inner()
            .map_err(|e| anyhow::Error::new(e.into_error()))
            .with_context(context)?
            .into_inner()
            .map_err(|e| anyhow::Error::new(e.into_error()))
            .with_context(context)?;
        staged.commit(&self.path)?;
        Ok(self.rows)
    }
}

/// A file that grows by whole lines and is never rewritten (a sweep's `runs.jsonl`): a kill
/// tears at most the line being written. Created with the mode the umask gives.
pub struct AppendFile {
    path: PathBuf,
    file: std::sync::Mutex<std::fs::File>,
}

impl AppendFile {
    /// Opens `path` for appending (creating it), cut to its first `keep_bytes` when given (a
    /// torn last line, left by a kill, is removed so that its run is redone).
    pub fn open(path: &Path, keep_bytes: Option<u64>) -> Result<Self> {
        let context = || format!("cannot write `{}`", path.display());
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(context)?;
        if let Some(len) = keep_bytes {
            file.set_len(len).with_context(context)?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            file: std::sync::Mutex::new(file),
        })
    }

    /// Appends `line` and a newline, in one write (from any thread).
    pub fn line(&self, line: &str) -> Result<()> {
        let mut text = String::with_capacity(line.len() + 1);
        text.push_str(line);
        text.push('\n');
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        file.write_all(text.as_bytes())
            .with_context(|| format!("cannot write `{}`", self.path.display()))
    }
}

/// Holds a directory for one command at a time: an advisory lock on `DIR/.lock`, released
/// when the process ends, even by a kill (the file a killed command leaves is stale: the
/// next command takes it). The holder removes the file when it ends normally.
pub struct DirLock {
    path: PathBuf,
    _file: std::fs::File,
}

/// Attempts at taking a lock whose file a finishing holder removed meanwhile.
const LOCK_ATTEMPTS: usize = 10;

impl DirLock {
    /// Takes the lock of `dir`, or fails at once with `busy` if another process holds it.
    pub fn take(dir: &Path, busy: &str) -> Result<Self> {
        let path = dir.join(".lock");
        let context = || format!("cannot lock `{}`", path.display());
        for _ in 0..LOCK_ATTEMPTS {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .truncate(false)
                .write(true)
                .open(&path)
                .with_context(context)?;
            match file.try_lock() {
                // A holder that ended may have removed the file between our open and our
                // lock: a lock on a removed file holds nothing, so try again.
                Ok(()) if is_at(&file, &path) => return Ok(Self { path, _file: file }),
                Ok(()) => continue,
                Err(std::fs::TryLockError::WouldBlock) => bail!("`{}`: {busy}", dir.display()),
                Err(std::fs::TryLockError::Error(e)) => return Err(e).with_context(context),
            }
        }
        bail!("`{}`: {busy}", dir.display())
    }
}

impl Drop for DirLock {
    /// Removes the lock file while still holding the lock (the lock goes with the handle).
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Whether the open `file` is the file at `path` now.
#[cfg(unix)]
fn is_at(file: &std::fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn is_at(_: &std::fs::File, path: &Path) -> bool {
    path.exists()
}

/// A path given on the command line that a command reads: a `--plant`, `--gains`,
/// `--config`, scenario or sweep file. Names of embedded presets are not files.
pub fn input_file(arg: &str) -> Option<&Path> {
    let p = Path::new(arg);
    p.is_file().then_some(p)
}

/// Refuses to write an output onto one of the inputs (`single --plant P --csv P` would
/// destroy the plant file) or two outputs onto one path (`simulate --plot . --csv leg.png`
/// would keep only one of them): compares file identities, so links and `./` spellings are
/// caught too. Every command passes all its inputs and outputs, before it writes anything.
pub fn refuse_input_as_output(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<()> {
    for (i, (out_what, out)) in outputs.iter().enumerate() {
        for (in_what, input) in inputs {
            if same_file(input, out) {
                bail!(
                    "{out_what} `{}` is the {in_what} this command reads: refusing to overwrite an input (choose another path)",
                    out.display()
                );
            }
        }
        for (other_what, other) in &outputs[..i] {
            if same_file(other, out) || output_identity(other) == output_identity(out) {
                bail!(
                    "{out_what} `{}` and {other_what} `{}` are one path: two outputs of this command cannot share a file (choose another path)",
                    out.display(),
                    other.display()
                );
            }
        }
    }
    Ok(())
}

/// The file `path` names, for comparing outputs that may not exist yet: its canonical path
/// if it exists, else its directory's canonical path and its name.
fn output_identity(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (std::fs::canonicalize(dir), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
    }
}

#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Raised by SIGINT and SIGTERM: the running loop stops at its next period, the files are
/// completed, and the command exits with status 130.
pub fn stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&flag))
            .context("cannot install the SIGINT/SIGTERM handler")?;
    }
    Ok(flag)
}

/// The exit status of a run stopped by a signal.
pub const INTERRUPTED: i32 = 130;

/// Longest run accepted without `--yes` (s of wall time, estimated).
pub const MAX_WALL_S: f64 = 3600.0;

/// Refuses a run estimated to take more than [`MAX_WALL_S`] unless `yes`.
pub fn check_wall_time(what: &str, periods: f64, per_period_s: f64, yes: bool) -> Result<()> {
    let estimate = periods * per_period_s;
    // NaN and infinity are refused too.
    let acceptable = estimate.is_finite() && estimate <= MAX_WALL_S;
    if !yes && !acceptable {
        bail!(
            "{what} would take about {} ({periods:.3e} control periods at ~{:.1} us each); pass --yes to run it anyway",
            human_duration(estimate),
            per_period_s * 1e6
        );
    }
    Ok(())
}

/// `3.2 h`, `12 min`, `41 s`, `2.1e5 years`.
pub fn human_duration(s: f64) -> String {
    const YEAR: f64 = 365.25 * 86400.0;
    if !s.is_finite() {
        "forever".into()
    } else if s >= 1000.0 * YEAR {
        format!("{:.2e} years", s / YEAR)
    } else if s >= YEAR {
        format!("{:.1} years", s / YEAR)
    } else if s >= 86400.0 {
        format!("{:.1} days", s / 86400.0)
    } else if s >= 3600.0 {
        format!("{:.1} h", s / 3600.0)
    } else if s >= 60.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{s:.0} s")
    }
}

/// A progress bar of `len` `unit`s that follows `counter` (work done, counted by the
/// workers) from a thread of its own until the returned guard is dropped.
pub fn follow_progress(
    counter: &'static std::sync::atomic::AtomicUsize,
    len: u64,
    unit: &str,
) -> FollowedBar {
    let bar = progress_bar(len, unit);
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let thread = {
        let (bar, done) = (bar.clone(), std::sync::Arc::clone(&done));
        std::thread::spawn(move || {
            use std::sync::atomic::Ordering::Relaxed;
            while !done.load(Relaxed) {
                bar.set_position(counter.load(Relaxed) as u64);
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
        })
    };
    FollowedBar {
        bar,
        done,
        thread: Some(thread),
    }
}

/// Stops following and clears the bar when dropped.
pub struct FollowedBar {
    bar: indicatif::ProgressBar,
    done: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for FollowedBar {
    fn drop(&mut self) {
        self.done.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.bar.finish_and_clear();
    }
}

/// A spinner on stderr with `message` and the time elapsed, for work whose length is not
/// known in advance (hidden when stderr is not a terminal); clear it with
/// `finish_and_clear`.
pub fn spinner(message: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        None,
        indicatif::ProgressDrawTarget::stderr_with_hz(4),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
        bar.set_style(style);
    }
    bar.set_message(message.to_owned());
    bar.enable_steady_tick(std::time::Duration::from_millis(250));
    bar
}

/// A progress bar on stderr (hidden when stderr is not a terminal): position, ETA.
pub fn progress_bar(len: u64, unit: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(len),
        indicatif::ProgressDrawTarget::stderr_with_hz(4),
    );
    let template =
        format!("{{wide_bar}} {{percent:>3}} % {{pos}}/{{len}} {unit} {{elapsed}} (ETA {{eta}})");
    if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
        bar.set_style(style);
    }
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn human_durations() {
        assert_eq!(human_duration(41.2), "41 s");
        assert_eq!(human_duration(720.0), "12 min");
        assert_eq!(human_duration(3.2 * 3600.0), "3.2 h");
        assert!(human_duration(1e12).ends_with("years"));
    }

    #[test]
    fn long_runs_are_refused_without_yes() {
        assert!(check_wall_time("x", 1e12, 1e-6, false).is_err());
        assert!(check_wall_time("x", 1e12, 1e-6, true).is_ok());
        assert!(check_wall_time("x", 1e6, 1e-6, false).is_ok());
        assert!(check_wall_time("x", f64::INFINITY, 1e-6, false).is_err());
    }
}
