//! What the commands write: stdout that a closed pipe ends quietly, output files opened
//! (and named in every error) before a run starts, CSV streamed row by row, a progress
//! bar with an ETA, a refusal of runs that would take hours, and Ctrl-C.
use anyhow::{bail, Context, Result};
use std::fs::File;
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

/// A file opened for writing before the run, whose errors name it.
pub struct OutFile {
    path: PathBuf,
    file: BufWriter<File>,
}

impl OutFile {
    /// Creates (truncates) `path` now, so that a bad path fails before any work.
    pub fn create(path: &Path) -> Result<Self> {
        let file =
            File::create(path).with_context(|| format!("cannot create `{}`", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            file: BufWriter::new(file),
        })
    }

    /// Writes `text` and closes the file.
    pub fn finish_with(mut self, text: &str) -> Result<()> {
        let path = self.path.clone();
        self.file
            .write_all(text.as_bytes())
            .and_then(|()| self.file.flush())
            .with_context(|| format!("cannot write `{}`", path.display()))
    }
}

/// A CSV file streamed row by row through a buffer. The first I/O error is kept (with
/// the path) and reported by [`CsvOut::finish`]; later rows are dropped.
pub struct CsvOut {
    path: PathBuf,
    writer: csv::Writer<BufWriter<File>>,
    error: Option<anyhow::Error>,
    rows: u64,
}

impl CsvOut {
    /// Creates `path` and writes the header now.
    pub fn create(path: &Path, header: &[String]) -> Result<Self> {
        let file =
            File::create(path).with_context(|| format!("cannot create `{}`", path.display()))?;
        let mut writer = csv::Writer::from_writer(BufWriter::with_capacity(1 << 16, file));
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

    /// Flushes; the first error of the run, if any, naming the file.
    pub fn finish(mut self) -> Result<u64> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.writer
            .flush()
            .with_context(|| format!("cannot write `{}`", self.path.display()))?;
        Ok(self.rows)
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
