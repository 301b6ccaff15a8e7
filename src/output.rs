//! What the commands write: stdout that a closed pipe ends quietly, output files opened
//! (and named in every error) before a run starts, CSV streamed row by row, a progress
//! bar with an ETA, a refusal of runs that would take hours, and Ctrl-C.
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
        let path = match std::fs::metadata(path) {
            Ok(meta) if !meta.is_file() => {
                let file = std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .with_context(context)?;
                return Ok(Staged::Direct(file));
            }
            Ok(_) => std::fs::canonicalize(path).with_context(context)?,
            Err(_) => path.to_path_buf(),
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
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .suffix(&suffix)
            .tempfile_in(dir)
            .with_context(context)?;
        Ok(Staged::Temp { temp, path })
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
            Staged::Temp { temp, path } => {
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

/// Draws or writes a file through `write(path to write)` and renames it onto `path` when
/// `write` succeeds (plots: plotters writes the file itself, by its extension).
pub fn write_via_temp<E: std::fmt::Display>(
    path: &Path,
    write: impl FnOnce(&Path) -> std::result::Result<(), E>,
) -> Result<()> {
    let staged = Staged::new(path, true)?;
    write(&staged.write_path(path))
        .map_err(|e| anyhow::anyhow!("cannot write `{}`: {e}", path.display()))?;
    staged.commit(path)
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
    writer: csv::Writer<BufWriter<Staged>>,
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
            writer,
            error: None,
            rows: 0,
        })
    }

    /// One row of numbers.
    pub fn row(&mut self, values: &[f64]) {
        if self.error.is_some() {
            return;
        }
        if let Err(e) = self.writer.serialize(values) {
            self.error = Some(
                anyhow::Error::new(e).context(format!("cannot write `{}`", self.path.display())),
            );
        } else {
            self.rows += 1;
        }
    }

    /// Flushes and renames the file onto its path; the first error of the run, if any,
    /// naming the file (the previous file at the path is then left as it was).
    pub fn finish(mut self) -> Result<u64> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let context = || format!("cannot write `{}`", self.path.display());
        let staged = self
            .writer
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

/// A path given on the command line that a command reads: a `--plant`, `--gains`,
/// `--config`, scenario or sweep file. Names of embedded presets are not files.
pub fn input_file(arg: &str) -> Option<&Path> {
    let p = Path::new(arg);
    p.is_file().then_some(p)
}

/// Refuses to write an output onto one of the inputs (`single --plant P --csv P` would
/// destroy the plant file): compares file identities, so links and `./` spellings are
/// caught too.
pub fn refuse_input_as_output(inputs: &[(&str, &Path)], outputs: &[(&str, &Path)]) -> Result<()> {
    for (out_what, out) in outputs {
        for (in_what, input) in inputs {
            if same_file(input, out) {
                bail!(
                    "{out_what} `{}` is the {in_what} this command reads: refusing to overwrite an input (choose another path)",
                    out.display()
                );
            }
        }
    }
    Ok(())
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
