//! The rig's log: fixed-size records pushed by the control loop into a preallocated
//! wait-free ring buffer (`rtrb`), written as CSV by a writer thread. The loop does no
//! file I/O and allocates nothing; the file is opened (and its header written) before the
//! run, and it is complete up to the last period on every exit path: the end of the run,
//! a fault, Ctrl-C and a panic (dropping the log joins the writer).
use crate::backend::RigBackend;
use crate::error::RigError;
use crate::supervisor::Supervised;
use pma_control::{RefSample, Reference};
use pma_loop::{Backend, End, MuscleStep, Period, Recorder, Start};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Version of the log format: replay refuses other versions.
pub const LOG_FORMAT: u32 = 1;

/// Records the ring buffer holds (65 s at 1 kHz): the writer only has to keep up on
/// average.
const RING_RECORDS: usize = 1 << 16;

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
    /// Controller states.
    pub diagnostics: pma_control::Diagnostics,
    /// What the row is.
    pub event: Event,
    /// The fault that ended the run (on the vent row), or `interrupted`.
    pub fault: Option<&'static str>,
}

/// CSV columns, in order.
pub const COLUMNS: [&str; 19] = [
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
    "proxy_m",
    "s_p",
    "s_q",
    "gain_hat",
    "disturbance_hat",
    "event",
    "fault",
];

impl LogRecord {
    fn fields(&self) -> [String; 19] {
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
}

/// The log: a [`Recorder`] of the supervised rig.
pub struct RigLog {
    producer: rtrb::Producer<LogRecord>,
    done: Arc<AtomicBool>,
    writer: Option<std::thread::JoinHandle<Result<u64, RigError>>>,
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

impl RigLog {
    /// Creates the file and writes `header` (each line as a `#` comment) and the column
    /// names, then starts the writer thread. Fails before the run if the file cannot be
    /// written. `reference` gives the reference at the activation (the loop's first row).
    /// `wait_when_full`: a lockstep run, which has no deadline, waits for the writer when
    /// the ring is full; a real-time run never waits (a record that does not fit is
    /// counted as dropped).
    pub fn create(
        path: &Path,
        header: &str,
        reference: Box<dyn Reference>,
        vent_valve_v: f64,
        wait_when_full: bool,
    ) -> Result<Self, RigError> {
        let file = File::create(path).map_err(|e| io_error(path, e))?;
        let mut out = BufWriter::new(file);
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
            let file_path = path.to_path_buf();
            std::thread::Builder::new()
                .name("pma-rig-log".into())
                .spawn(move || write_rows(consumer, csv, &done, &file_path))
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
            diagnostics: pma_control::Diagnostics::NONE,
            event: Event::Period,
            fault: None,
        };
        Ok(Self {
            producer,
            done,
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
        let mut record = r;
        while let Err(rtrb::PushError::Full(back)) = self.producer.push(record) {
            if !self.wait_when_full || self.writer.as_ref().is_none_or(|w| w.is_finished()) {
                self.dropped += 1;
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

    /// Waits for the writer to write everything and closes the file.
    pub fn finish(mut self) -> Result<LogSummary, RigError> {
        let rows = self.join()?;
        Ok(LogSummary {
            path: self.path.clone(),
            rows,
            dropped: self.dropped,
        })
    }

    fn join(&mut self) -> Result<u64, RigError> {
        self.done.store(true, Ordering::Release);
        match self.writer.take() {
            Some(t) => t.join().unwrap_or_else(|_| {
                Err(RigError::Io {
                    path: self.path.display().to_string(),
                    message: "the log writer thread panicked".into(),
                })
            }),
            None => Ok(0),
        }
    }
}

/// A log dropped without `finish` (a panic unwinding) still writes everything pushed.
impl Drop for RigLog {
    fn drop(&mut self) {
        let _ = self.join();
    }
}

fn write_rows(
    mut consumer: rtrb::Consumer<LogRecord>,
    mut csv: csv::Writer<BufWriter<File>>,
    done: &AtomicBool,
    path: &Path,
) -> Result<u64, RigError> {
    let mut rows = 0u64;
    loop {
        // Read `done` before draining: whatever was pushed before it was set is drained.
        let finished = done.load(Ordering::Acquire);
        let mut wrote = false;
        while let Ok(r) = consumer.pop() {
            csv.write_record(r.fields())
                .map_err(|e| io_error(path, e))?;
            rows += 1;
            wrote = true;
        }
        if finished {
            break;
        }
        if !wrote {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    csv.flush().map_err(|e| io_error(path, e))?;
    let file = csv
        .into_inner()
        .map_err(|e| io_error(path, e.error()))?
        .into_inner()
        .map_err(|e| io_error(path, e.error()))?;
    file.sync_all().map_err(|e| io_error(path, e))?;
    Ok(rows)
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
            diagnostics: p.output.control.diagnostics,
            event: Event::Period,
            fault: None,
        };
        self.push(r);
    }

    fn end(&mut self, end: &End<crate::supervisor::Fault<crate::daq::DaqError>>, _t_s: f64) {
        let fault = match end {
            End::Completed => None,
            End::Stopped => Some("interrupted"),
            End::Fault { error, .. } => Some(error.name()),
        };
        self.vent_row(fault);
    }
}
