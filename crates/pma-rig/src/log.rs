//! The rig's log: fixed-size records pushed by the control loop into a preallocated
//! wait-free ring buffer (`rtrb`), written as CSV by a writer thread. The loop does no
//! file I/O and allocates nothing; the file is created (never over an existing one) and its
//! header written before the run, and it is complete up to the last period on every exit
//! path: the end of the run, a fault, Ctrl-C and a panic (dropping the log joins the
//! writer). It ends with the vent row and a digest line, `# sha256 <hex> rows <n>`, over
//! every byte before it, which replay checks.
//!
//! A log that cannot be written (a full disk, a vanished device) raises the run's
//! [`Alarm`]: the supervisor vents and stops with `log-error` at the next period.
use crate::backend::RigBackend;
use crate::error::RigError;
use pma_control::supervisor::{Alarm, Supervised};
use pma_control::MuscleStep;
use pma_control::{RefSample, Reference};
use pma_loop::{Backend, End, Period, Recorder, Start};
use sha2::{Digest, Sha256};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Version of the log format: replay refuses other versions. 2: the digest line.
pub const LOG_FORMAT: u32 = 2;

/// The last line's prefix: `# sha256 <hex> rows <n>`.
pub const DIGEST_PREFIX: &str = "# sha256 ";

/// Records the ring buffer holds (65 s at 1 kHz): the writer only has to keep up on
/// average.
const RING_RECORDS: usize = 1 << 16;

/// Most records a lockstep run may be ahead of its writer (1 s at 1 kHz).
const LOCKSTEP_LAG_RECORDS: usize = 1000;

/// What a row is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// The activation: the reading and reference the controller was reset with.
    Activate,
    /// A control period.
    Period,
    /// The vent at the end of the run.
    Vent,
}

impl Event {
    /// Name in the log.
    pub fn name(self) -> &'static str {
        match self {
            Event::Activate => "activate",
            Event::Period => "",
            Event::Vent => "vent",
        }
    }
}

/// One row of the log (fixed size, `Copy`: it crosses the ring buffer by value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogRecord {
    /// Period index (0: activation).
    pub period: u64,
    /// Time (s).
    pub t_s: f64,
    /// Time since the previous reading (s).
    pub dt_s: f64,
    /// Reference (position, velocity, acceleration).
    pub reference: RefSample,
    /// Measured contraction (m).
    pub position_m: f64,
    /// Sensor voltage (V).
    pub position_v: f64,
    /// Controller command (Pa), before the supervisor.
    pub command_pa: f64,
    /// Command sent to the valve (Pa), after the supervisor.
    pub valve_cmd_pa: f64,
    /// Valve voltage (V).
    pub valve_v: f64,
    /// The pressure channel's voltage (V) and pressure (Pa); NaN without the channel.
    pub pressure: [f64; 2],
    /// Controller states.
    pub diagnostics: pma_control::Diagnostics,
    /// What the row is.
    pub event: Event,
    /// The fault that ended the run (on the vent row), or `interrupted`.
    pub fault: Option<&'static str>,
}

/// CSV columns, in order.
pub const COLUMNS: [&str; 21] = [
    "t_s",
    "period",
    "dt_s",
    "reference_m",
    "reference_velocity_m_s",
    "reference_acceleration_m_s2",
    "position_m",
    "position_v",
    "velocity_m_s",
    "command_pa",
    "valve_cmd_pa",
    "valve_v",
    "pressure_v",
    "pressure_pa",
    "proxy_m",
    "s_p",
    "s_q",
    "gain_hat",
    "disturbance_hat",
    "event",
    "fault",
];

impl LogRecord {
    fn fields(&self) -> [String; 21] {
        let d = &self.diagnostics;
        let f = |v: f64| v.to_string();
        [
            f(self.t_s),
            self.period.to_string(),
            f(self.dt_s),
            f(self.reference.position_m),
            f(self.reference.velocity_m_s),
            f(self.reference.acceleration_m_s2),
            f(self.position_m),
            f(self.position_v),
            f(d.velocity_m_s),
            f(self.command_pa),
            f(self.valve_cmd_pa),
            f(self.valve_v),
            optional(self.pressure[0]),
            optional(self.pressure[1]),
            f(d.proxy_position_m),
            f(d.s_p),
            f(d.s_q),
            f(d.gain_hat),
            f(d.disturbance_hat),
            self.event.name().to_owned(),
            self.fault.unwrap_or("").to_owned(),
        ]
    }
}

/// A measurement the rig may not have: empty when NaN.
fn optional(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        v.to_string()
    }
}

/// How the log went.
#[derive(Debug, Clone, PartialEq)]
pub struct LogSummary {
    /// Path.
    pub path: PathBuf,
    /// Rows written.
    pub rows: u64,
    /// Records the loop could not push because the writer fell behind (0 unless the disk
    /// stalled for over a minute).
    pub dropped: u64,
    /// Why the log is incomplete, if it is (the run was stopped with `log-error`).
    pub error: Option<String>,
}

/// The log: a [`Recorder`] of the supervised rig.
pub struct RigLog {
    producer: rtrb::Producer<LogRecord>,
    done: Arc<AtomicBool>,
    alarm: Arc<Alarm>,
    writer: Option<std::thread::JoinHandle<(u64, Result<(), RigError>)>>,
    path: PathBuf,
    dropped: u64,
    last: LogRecord,
    reference: Box<dyn Reference>,
    vent_valve_v: f64,
    wait_when_full: bool,
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> RigError {
    RigError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// What a log is written to: a file (or, in tests, a disk that fills up).
trait Sink: Write + Send {
    /// Makes what was written durable.
    fn sync(&mut self) -> std::io::Result<()>;
}

impl Sink for File {
    fn sync(&mut self) -> std::io::Result<()> {
        self.sync_all()
    }
}

/// What a log records besides its rows.
pub struct LogSpec<'a> {
    /// The header, one `#` comment per line.
    pub header: &'a str,
    /// The reference, for the activation row.
    pub reference: Box<dyn Reference>,
    /// The valve's vent voltage, for the vent row.
    pub vent_valve_v: f64,
    /// A lockstep run, which has no deadline, waits for the writer (keeping within a
    /// second of it); a real-time run never waits (a record that does not fit raises the
    /// alarm).
    pub wait_when_full: bool,
    /// Raised when the log fails.
    pub alarm: Arc<Alarm>,
}

/// Where a log's bytes go: the sink, through a running SHA-256 of everything written.
struct Hashing {
    sink: Box<dyn Sink>,
    hash: Sha256,
}

impl Write for Hashing {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.sink.write(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.sink.flush()
    }
}

type LogWriter = csv::Writer<BufWriter<Hashing>>;

/// Creates a new log file: never over an existing file, and only a regular file (a log
/// into `/dev/null` or a pipe would run the experiment and keep nothing).
fn create_new(path: &Path) -> Result<File, RigError> {
    if let Ok(meta) = std::fs::metadata(path) {
        let what = if meta.is_file() {
            "exists: a rig log is never overwritten (move it, or name another file: `rig run --log`, `rig excite --out`)"
        } else {
            "is not a regular file: a rig log must be a new file that keeps what it records"
        };
        return Err(io_error(path, what));
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| io_error(path, e))
}

impl RigLog {
    /// Creates the file (which must not exist) and writes the header (each line as a `#`
    /// comment) and the column names, then starts the writer thread. Fails before the run
    /// if the file cannot be written.
    pub fn create(path: &Path, spec: LogSpec<'_>) -> Result<Self, RigError> {
        let file = create_new(path)?;
        Self::on_sink(Box::new(file), path, spec)
    }

    /// [`RigLog::create`] on an opened sink.
    fn on_sink(sink: Box<dyn Sink>, path: &Path, spec: LogSpec<'_>) -> Result<Self, RigError> {
        let LogSpec {
            header,
            reference,
            vent_valve_v,
            wait_when_full,
            alarm,
        } = spec;
        let mut out = BufWriter::new(Hashing {
            sink,
            hash: Sha256::new(),
        });
        for line in header.lines() {
            writeln!(out, "# {line}").map_err(|e| io_error(path, e))?;
        }
        let mut csv = csv::Writer::from_writer(out);
        csv.write_record(COLUMNS).map_err(|e| io_error(path, e))?;
        csv.flush().map_err(|e| io_error(path, e))?;
        let (producer, consumer) = rtrb::RingBuffer::new(RING_RECORDS);
        let done = Arc::new(AtomicBool::new(false));
        let writer = {
            let done = Arc::clone(&done);
            let alarm = Arc::clone(&alarm);
            let file_path = path.to_path_buf();
            std::thread::Builder::new()
                .name("pma-rig-log".into())
                .spawn(move || {
                    let mut rows = 0;
                    let r = write_rows(consumer, csv, &done, &file_path, &mut rows);
                    if let Err(e) = &r {
                        alarm.raise(e.to_string());
                    }
                    (rows, r)
                })
                .map_err(|e| io_error(path, e))?
        };
        let blank = LogRecord {
            period: 0,
            t_s: 0.0,
            dt_s: 0.0,
            reference: RefSample::default(),
            position_m: f64::NAN,
            position_v: f64::NAN,
            command_pa: 0.0,
            valve_cmd_pa: 0.0,
            valve_v: vent_valve_v,
            pressure: [f64::NAN; 2],
            diagnostics: pma_control::Diagnostics::NONE,
            event: Event::Period,
            fault: None,
        };
        Ok(Self {
            producer,
            done,
            alarm,
            writer: Some(writer),
            path: path.to_path_buf(),
            dropped: 0,
            last: blank,
            reference,
            vent_valve_v,
            wait_when_full,
        })
    }

    fn push(&mut self, r: LogRecord) {
        self.last = r;
        if self.wait_when_full {
            // A lockstep run has no deadline: it keeps within a second of the writer, so that
            // it stops where its log stopped, as a real-time run does within milliseconds.
            while RING_RECORDS - self.producer.slots() >= LOCKSTEP_LAG_RECORDS
                && self.writer.as_ref().is_some_and(|w| !w.is_finished())
            {
                std::thread::yield_now();
            }
        }
        let mut record = r;
        while let Err(rtrb::PushError::Full(back)) = self.producer.push(record) {
            if !self.wait_when_full || self.writer.as_ref().is_none_or(|w| w.is_finished()) {
                self.dropped += 1;
                self.alarm
                    .raise("the log writer fell behind: records were lost");
                return;
            }
            std::thread::yield_now();
            record = back;
        }
    }

    /// Writes the vent row of a run that ended with `fault` (or `interrupted`) outside
    /// the loop (a panic).
    pub fn vent_row(&mut self, fault: Option<&'static str>) {
        let r = LogRecord {
            period: self.last.period + 1,
            dt_s: 0.0,
            command_pa: 0.0,
            valve_cmd_pa: 0.0,
            valve_v: self.vent_valve_v,
            diagnostics: pma_control::Diagnostics::NONE,
            event: Event::Vent,
            fault,
            ..self.last
        };
        self.push(r);
    }

    /// Waits for the writer to write everything and closes the file. A log that failed
    /// says why in [`LogSummary::error`]: the run's report is never lost with it.
    pub fn finish(mut self) -> LogSummary {
        let (rows, result) = self.join();
        let error = result.err().map(|e| e.to_string());
        let error = error.or_else(|| self.alarm.is_raised().then(|| self.alarm.message()));
        LogSummary {
            path: self.path.clone(),
            rows,
            dropped: self.dropped,
            error,
        }
    }

    /// Rows written, and how the writing ended.
    fn join(&mut self) -> (u64, Result<(), RigError>) {
        self.done.store(true, Ordering::Release);
        match self.writer.take() {
            Some(t) => t.join().unwrap_or_else(|_| {
                (
                    0,
                    Err(RigError::Io {
                        path: self.path.display().to_string(),
                        message: "the log writer thread panicked".into(),
                    }),
                )
            }),
            None => (0, Ok(())),
        }
    }
}

/// A log dropped without `finish` (a panic unwinding) still writes everything pushed.
impl Drop for RigLog {
    fn drop(&mut self) {
        let _ = self.join();
    }
}

/// Writes rows until `done`, counting them in `rows` (also when it fails).
fn write_rows(
    mut consumer: rtrb::Consumer<LogRecord>,
    mut csv: LogWriter,
    done: &AtomicBool,
    path: &Path,
    rows: &mut u64,
) -> Result<(), RigError> {
    loop {
        // Read `done` before draining: whatever was pushed before it was set is drained.
        let finished = done.load(Ordering::Acquire);
        let mut wrote = false;
        while let Ok(r) = consumer.pop() {
            csv.write_record(r.fields())
                .map_err(|e| io_error(path, e))?;
            *rows += 1;
            wrote = true;
        }
        if finished {
            break;
        }
        if wrote {
            // Idle: hand what was written to the file now, so that a full disk is seen
            // within a few periods rather than at the end of the run.
            csv.flush().map_err(|e| io_error(path, e))?;
        } else {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    csv.flush().map_err(|e| io_error(path, e))?;
    let Hashing { mut sink, hash } = csv
        .into_inner()
        .map_err(|e| io_error(path, e.error()))?
        .into_inner()
        .map_err(|e| io_error(path, e.error()))?;
    writeln!(sink, "{DIGEST_PREFIX}{} rows {rows}", hex(&hash.finalize()))
        .and_then(|()| sink.sync())
        .map_err(|e| io_error(path, e))
}

/// `path` with every `{time}` replaced by the UTC time now, `20261123T101500Z`: the
/// shipped configurations name each run's log by its start, so that runs never collide.
pub fn expand_time(path: &Path) -> PathBuf {
    let text = path.to_string_lossy();
    if !text.contains("{time}") {
        return path.to_path_buf();
    }
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    PathBuf::from(text.replace("{time}", &utc_stamp(secs)))
}

/// `YYYYMMDDTHHMMSSZ` of seconds since the Unix epoch (civil date from day count:
/// Howard Hinnant's `civil_from_days`).
fn utc_stamp(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}{month:02}{day:02}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// Lower-case hexadecimal.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

type Rig = Supervised<RigBackend>;

impl Recorder<Rig, MuscleStep> for RigLog {
    fn start(&mut self, s: &Start<'_, Rig>) {
        let r = LogRecord {
            period: 0,
            t_s: s.t_s,
            dt_s: 0.0,
            reference: self.reference.sample(s.t_s),
            position_m: s.reading.position_m,
            position_v: s.truth.position_v,
            command_pa: *s.held,
            valve_cmd_pa: *s.held,
            valve_v: s.truth.valve_v,
            pressure: [s.truth.pressure_v, s.truth.pressure_pa],
            diagnostics: pma_control::Diagnostics::NONE,
            event: Event::Activate,
            fault: None,
        };
        self.push(r);
    }

    fn record(&mut self, p: &Period<'_, Rig, MuscleStep>) {
        let r = LogRecord {
            period: p.index,
            t_s: p.t_s,
            dt_s: p.dt_s,
            reference: p.output.reference,
            position_m: p.reading.position_m,
            position_v: p.truth.position_v,
            command_pa: p.output.control.pressure_cmd_pa,
            valve_cmd_pa: *p.written,
            valve_v: p.backend.inner().truth().valve_v,
            pressure: [p.truth.pressure_v, p.truth.pressure_pa],
            diagnostics: p.output.control.diagnostics,
            event: Event::Period,
            fault: None,
        };
        self.push(r);
    }

    fn end(&mut self, end: &End<pma_control::supervisor::Fault<crate::daq::DaqError>>, _t_s: f64) {
        let fault = match end {
            End::Completed => None,
            End::Stopped => Some("interrupted"),
            End::Fault { error, .. } => Some(error.name()),
        };
        self.vent_row(fault);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pma_control::SineReference;

    fn record(period: u64) -> LogRecord {
        LogRecord {
            period,
            t_s: period as f64 * 1e-3,
            dt_s: 1e-3,
            reference: RefSample::default(),
            position_m: 0.01,
            position_v: 2.0,
            command_pa: 1e5,
            valve_cmd_pa: 1e5,
            valve_v: 1.0,
            pressure: [f64::NAN; 2],
            diagnostics: pma_control::Diagnostics::NONE,
            event: Event::Period,
            fault: None,
        }
    }

    /// A disk that takes `room` bytes, then fails every write with ENOSPC.
    struct FillingDisk {
        room: usize,
    }

    impl Write for FillingDisk {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.room == 0 {
                return Err(std::io::Error::from_raw_os_error(28));
            }
            let n = buf.len().min(self.room);
            self.room -= n;
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Sink for FillingDisk {
        fn sync(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// Regression: on a full disk the log stopped at 2 s while the muscle kept moving to
    /// 10 s, and the run ended with exit 1 and no report. A log that cannot be written now
    /// raises the run's alarm (the supervisor vents at the next period) and `finish` says
    /// why instead of failing.
    #[test]
    fn a_log_on_a_full_disk_raises_the_alarm_and_reports_why() {
        let alarm = Alarm::new();
        let mut log = RigLog::on_sink(
            Box::new(FillingDisk { room: 200_000 }),
            Path::new("full.csv"),
            LogSpec {
                header: "header",
                reference: Box::new(SineReference::paper()),
                vent_valve_v: 0.0,
                wait_when_full: true,
                alarm: Arc::clone(&alarm),
            },
        )
        .expect("the header fits");
        for k in 1..=20_000 {
            log.push(record(k));
        }
        let t0 = std::time::Instant::now();
        while !alarm.is_raised() && t0.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(1));
        }
        assert!(alarm.is_raised(), "the alarm was not raised");
        assert!(
            alarm.message().contains("No space left"),
            "{}",
            alarm.message()
        );
        let summary = log.finish();
        assert!(
            summary
                .error
                .as_deref()
                .is_some_and(|e| e.contains("No space left")),
            "{summary:?}"
        );
    }

    #[test]
    fn a_log_never_overwrites_a_file_nor_writes_into_a_device() {
        let dir = std::env::temp_dir().join(format!("pma-rig-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let existing = dir.join("old.csv");
        std::fs::write(&existing, "keep me").unwrap();
        let e = create_new(&existing).unwrap_err().to_string();
        assert!(e.contains("never overwritten"), "{e}");
        assert_eq!(std::fs::read_to_string(&existing).unwrap(), "keep me");
        let e = create_new(Path::new("/dev/null")).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn utc_stamps_of_known_instants() {
        assert_eq!(utc_stamp(0), "19700101T000000Z");
        // 2020-05-25 (the paper's publication date) 12:34:56 UTC.
        assert_eq!(utc_stamp(1_590_410_096), "20200525T123456Z");
        assert_eq!(utc_stamp(951_782_400), "20000229T000000Z");
    }
}
