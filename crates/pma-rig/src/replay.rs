//! Replay: a rig log's measurements, references and periods fed back through the same
//! controller, rebuilt from the configuration and gains in the log's header. For a log
//! of the same format the commands must come out bit for bit.
//!
//! A log is checked before it is trusted: its digest line (a SHA-256 of every byte before
//! it, written when the log was closed) must match, so a truncated or edited log is
//! refused; its rows must run from the activation through contiguous periods to the vent
//! row; and every column the header determines is recomputed (time from the periods, the
//! position from the sensor's volts, the reference, the supervisor's clamp and rate limit,
//! the valve's volts). The controller's columns are compared and counted.
use crate::config::RigConfig;
use crate::error::RigError;
use crate::log::{hex, DIGEST_PREFIX, LOG_FORMAT};
use pma_control::{
    ControllerConfig, Fault, Measurement, MuscleStep, MuscleTask, RefSample, SmoothStart,
    Supervised,
};
use pma_loop::{Backend, End, LoopSettings, Period, Recorder, Started};
use sha2::{Digest, Sha256};
use std::path::Path;

/// Markers of the header's sections.
pub(crate) const CONFIG_BEGIN: &str = "begin config";
pub(crate) const CONFIG_END: &str = "end config";
pub(crate) const GAINS_BEGIN: &str = "begin gains";
pub(crate) const GAINS_END: &str = "end gains";
/// The header line that says where the reference started (m).
pub(crate) const REFERENCE_START: &str = "reference start_m = ";
/// The excitation section of an excitation's log (`rig excite`).
pub(crate) const EXCITATION_BEGIN: &str = "begin excitation";
/// Its end.
pub(crate) const EXCITATION_END: &str = "end excitation";

/// Valve volts recomputed from the command may differ from the log's by the clamp onto the
/// output range (V).
const VOLTS_TOLERANCE: f64 = 1e-9;

/// The first header line of every log.
pub fn format_line() -> String {
    format!(
        "pma-exo rig log, format {LOG_FORMAT}, pma-exo {}",
        env!("CARGO_PKG_VERSION")
    )
}

/// What a replay found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReplayReport {
    /// The log.
    pub log: String,
    /// Controller.
    pub controller: String,
    /// Control periods replayed.
    pub periods: u64,
    /// Largest `|replayed - logged|` command (Pa).
    pub max_abs_difference_pa: f64,
    /// Periods whose command or controller state differs in any bit.
    pub mismatches: u64,
    /// The fault the log ended with (`interrupted` for a signal), if any.
    pub fault: Option<String>,
}

fn log_error(path: &Path, message: impl Into<String>) -> RigError {
    RigError::Log {
        path: path.display().to_string(),
        message: message.into(),
    }
}

fn section(header: &[String], begin: &str, end: &str) -> Option<String> {
    let start = header.iter().position(|l| l == begin)? + 1;
    let stop = header.iter().position(|l| l == end)?;
    (stop >= start).then(|| header[start..stop].join("\n"))
}

/// Splits the text into the body and its digest line, and checks the digest.
fn check_digest<'t>(path: &Path, text: &'t str) -> Result<(&'t str, u64), RigError> {
    let body_end = text.trim_end_matches('\n').rfind('\n').map_or(0, |i| i + 1);
    let (body, last) = text.split_at(body_end);
    let truncated = || {
        log_error(
            path,
            "no digest line at the end: the log is truncated (or was cut by a kill or a full disk) and cannot be trusted",
        )
    };
    let rest = last
        .trim_end()
        .strip_prefix(DIGEST_PREFIX)
        .ok_or_else(truncated)?;
    let (digest, rows) = rest.split_once(" rows ").ok_or_else(truncated)?;
    let rows: u64 = rows.parse().map_err(|_| truncated())?;
    let actual = hex(&Sha256::digest(body.as_bytes()));
    if actual != digest {
        return Err(log_error(
            path,
            format!("its contents do not match its digest (sha256 {actual}, logged {digest}): the log was edited or damaged"),
        ));
    }
    Ok((body, rows))
}

/// The header: the `#` lines before the column names.
fn header_lines(body: &str) -> Vec<String> {
    body.lines()
        .take_while(|l| l.starts_with('#'))
        .map(|l| {
            l.strip_prefix("# ")
                .unwrap_or(l.trim_start_matches('#'))
                .to_owned()
        })
        .collect()
}

/// What the header says: the configuration, the gains and the reference's start.
struct Header {
    config: RigConfig,
    gains: ControllerConfig,
    excitation: Option<pma_control::ExcitationSpec>,
    reference: SmoothStart,
}

fn parse_header(path: &Path, header: &[String]) -> Result<Header, RigError> {
    match header.first() {
        Some(first) if *first == format_line() => {}
        Some(first) => {
            return Err(log_error(
                path,
                format!(
                    "written by `{first}`; this is `{}`: replay needs the same version",
                    format_line()
                ),
            ))
        }
        None => return Err(log_error(path, "no header: not a pma-exo rig log")),
    }
    let config_text = section(header, CONFIG_BEGIN, CONFIG_END)
        .ok_or_else(|| log_error(path, "the header has no configuration section"))?;
    let gains_text = section(header, GAINS_BEGIN, GAINS_END)
        .ok_or_else(|| log_error(path, "the header has no gains section"))?;
    let start_m: f64 = header
        .iter()
        .find_map(|l| l.strip_prefix(REFERENCE_START))
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| log_error(path, "the header does not say where the reference started"))?;
    let config = RigConfig::from_toml_str(&config_text, &format!("{} (header)", path.display()))?;
    let gains = ControllerConfig::from_toml_str(&gains_text)?;
    let excitation = match section(header, EXCITATION_BEGIN, EXCITATION_END) {
        Some(text) => Some(
            toml::from_str(&text)
                .map_err(|e| log_error(path, format!("the header's excitation section: {e}")))?,
        ),
        None => None,
    };
    let reference = config.reference(start_m);
    Ok(Header {
        config,
        gains,
        excitation,
        reference,
    })
}

/// Column indices of a log.
struct Columns {
    t: usize,
    period: usize,
    dt: usize,
    reference: [usize; 3],
    position: usize,
    position_v: usize,
    velocity: usize,
    command: usize,
    valve_cmd: usize,
    valve_v: usize,
    states: [usize; 5],
    event: usize,
    fault: usize,
}

impl Columns {
    fn of(path: &Path, names: &csv::StringRecord) -> Result<Self, RigError> {
        let col = |name: &str| {
            names
                .iter()
                .position(|h| h == name)
                .ok_or_else(|| log_error(path, format!("no column `{name}`")))
        };
        Ok(Self {
            t: col("t_s")?,
            period: col("period")?,
            dt: col("dt_s")?,
            reference: [
                col("reference_m")?,
                col("reference_velocity_m_s")?,
                col("reference_acceleration_m_s2")?,
            ],
            position: col("position_m")?,
            position_v: col("position_v")?,
            velocity: col("velocity_m_s")?,
            command: col("command_pa")?,
            valve_cmd: col("valve_cmd_pa")?,
            valve_v: col("valve_v")?,
            states: [
                col("proxy_m")?,
                col("s_p")?,
                col("s_q")?,
                col("gain_hat")?,
                col("disturbance_hat")?,
            ],
            event: col("event")?,
            fault: col("fault")?,
        })
    }
}

/// One row of a log, parsed: what the loop saw, did and the controller reported.
#[derive(Debug, Clone, Copy)]
struct LogRow {
    number: usize,
    period: f64,
    t_s: f64,
    dt_s: f64,
    reference: RefSample,
    position_m: f64,
    position_v: f64,
    /// `command_pa`, then the controller's states (velocity, proxy, S_p, S_q, gain,
    /// disturbance), as logged.
    control: [f64; 7],
    valve_cmd_pa: f64,
    valve_v: f64,
}

/// A log's rows: the activation, the periods, the vent and its fault.
struct Rows {
    activation: LogRow,
    periods: Vec<LogRow>,
    vent: LogRow,
    fault: Option<String>,
}

fn parse_rows(path: &Path, body: &str, digest_rows: u64) -> Result<Rows, RigError> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_reader(body.as_bytes());
    let names = reader
        .headers()
        .map_err(|e| log_error(path, e.to_string()))?
        .clone();
    let c = Columns::of(path, &names)?;
    let mut activation = None;
    let mut periods = Vec::new();
    let mut vent = None;
    let mut fault = None;
    let mut count = 0u64;
    for (i, record) in reader.records().enumerate() {
        let record = record.map_err(|e| log_error(path, e.to_string()))?;
        let number = i + 1;
        count += 1;
        let text = |k: usize| record.get(k).unwrap_or("");
        let num = |k: usize| -> Result<f64, RigError> {
            let s = text(k);
            s.parse::<f64>()
                .map_err(|_| log_error(path, format!("row {number}: `{s}` is not a number")))
        };
        let row = LogRow {
            number,
            period: num(c.period)?,
            t_s: num(c.t)?,
            dt_s: num(c.dt)?,
            reference: RefSample {
                position_m: num(c.reference[0])?,
                velocity_m_s: num(c.reference[1])?,
                acceleration_m_s2: num(c.reference[2])?,
            },
            position_m: num(c.position)?,
            position_v: num(c.position_v)?,
            control: [
                num(c.command)?,
                num(c.velocity)?,
                num(c.states[0])?,
                num(c.states[1])?,
                num(c.states[2])?,
                num(c.states[3])?,
                num(c.states[4])?,
            ],
            valve_cmd_pa: num(c.valve_cmd)?,
            valve_v: num(c.valve_v)?,
        };
        let (event, row_fault) = (text(c.event), text(c.fault));
        if vent.is_some() {
            return Err(log_error(
                path,
                format!("row {number}: a row after the vent row"),
            ));
        }
        if event != "vent" && !row_fault.is_empty() {
            return Err(log_error(
                path,
                format!("row {number}: a fault (`{row_fault}`) outside the vent row"),
            ));
        }
        match (event, activation.is_some()) {
            ("activate", false) => activation = Some(row),
            ("", true) => periods.push(row),
            ("vent", true) => {
                vent = Some(row);
                fault = (!row_fault.is_empty()).then(|| row_fault.to_owned());
            }
            ("activate", true) => {
                return Err(log_error(
                    path,
                    format!("row {number}: a second activation"),
                ))
            }
            ("", false) | ("vent", false) => {
                return Err(log_error(
                    path,
                    format!("row {number}: a row before the activation row"),
                ))
            }
            (other, _) => {
                return Err(log_error(
                    path,
                    format!("row {number}: unknown event `{other}`"),
                ))
            }
        }
    }
    if count != digest_rows {
        return Err(log_error(
            path,
            format!("{count} rows, but the digest line says {digest_rows}"),
        ));
    }
    let activation =
        activation.ok_or_else(|| log_error(path, "no activation row: nothing to replay"))?;
    let vent =
        vent.ok_or_else(|| log_error(path, "no vent row at the end: the log is incomplete"))?;
    Ok(Rows {
        activation,
        periods,
        vent,
        fault,
    })
}

fn differs(path: &Path, row: &LogRow, name: &str, logged: f64, expected: f64) -> RigError {
    log_error(
        path,
        format!(
            "row {}: {name} is {logged:?}, but the log's own header and earlier rows give {expected:?}: the log was edited or is not from this configuration",
            row.number
        ),
    )
}

/// Fails unless `logged` equals `expected` bit for bit.
fn exact(
    path: &Path,
    row: &LogRow,
    name: &str,
    logged: f64,
    expected: f64,
) -> Result<(), RigError> {
    if logged.to_bits() == expected.to_bits() {
        Ok(())
    } else {
        Err(differs(path, row, name, logged, expected))
    }
}

/// The log as a backend of the loop: its readings, periods and (checked) valve commands
/// played back, so that the controller and the supervisor run as they ran on the rig.
struct LogPlayer<'a> {
    path: &'a Path,
    header: &'a Header,
    rows: &'a Rows,
    /// Index of the current period row (none read yet: `None`).
    at: Option<usize>,
    elapsed: u64,
}

impl LogPlayer<'_> {
    fn row(&self) -> &LogRow {
        match self.at {
            Some(k) => &self.rows.periods[k],
            None => &self.rows.activation,
        }
    }

    /// The position the sensor's volts give, checked against the logged one.
    fn measurement(&self) -> Result<Measurement, RigError> {
        let row = self.row();
        let position_m = self.header.config.calibration.position_m(row.position_v);
        exact(self.path, row, "position_m", row.position_m, position_m)?;
        Ok(Measurement { position_m })
    }

    fn check_valve_v(&self, valve_cmd_pa: f64) -> Result<(), RigError> {
        let row = self.row();
        let expected = self.header.config.calibration.valve_v(valve_cmd_pa);
        if (row.valve_v - expected).abs() > VOLTS_TOLERANCE {
            return Err(differs(self.path, row, "valve_v", row.valve_v, expected));
        }
        Ok(())
    }
}

impl Backend for LogPlayer<'_> {
    type Reading = Measurement;
    type Command = f64;
    type Truth = LogRow;
    type Error = RigError;

    fn period_s(&self) -> f64 {
        self.header.config.period_s
    }

    fn start(&mut self) -> Result<Started<Measurement, f64>, RigError> {
        let row = self.rows.activation;
        exact(self.path, &row, "period", row.period, 0.0)?;
        let reading = self.measurement()?;
        self.check_valve_v(row.valve_cmd_pa)?;
        Ok(Started {
            t_s: row.t_s,
            reading,
            command: row.valve_cmd_pa,
        })
    }

    /// The next period row: its number and time follow from the ones before.
    fn wait(&mut self) -> Result<u32, RigError> {
        let k = self.at.map_or(0, |k| k + 1);
        let period_s = self.period_s();
        let row = self.rows.periods.get(k).ok_or_else(|| {
            log_error(
                self.path,
                "the log ends before its run: a period row is missing",
            )
        })?;
        exact(self.path, row, "period", row.period, (k + 1) as f64)?;
        let n = (row.dt_s / period_s).round();
        if !(n >= 1.0 && f64::from(n as u32) * period_s == row.dt_s) {
            return Err(differs(self.path, row, "dt_s", row.dt_s, period_s));
        }
        self.elapsed += n as u64;
        let t = self.rows.activation.t_s + self.elapsed as f64 * period_s;
        exact(self.path, row, "t_s", row.t_s, t)?;
        self.at = Some(k);
        Ok(n as u32)
    }

    fn read(&mut self) -> Result<Measurement, RigError> {
        self.measurement()
    }

    /// The command as the supervisor applied it must be the logged one.
    fn write(&mut self, command: &f64) -> Result<f64, RigError> {
        let row = *self.row();
        exact(self.path, &row, "valve_cmd_pa", row.valve_cmd_pa, *command)?;
        self.check_valve_v(*command)?;
        Ok(*command)
    }

    fn truth(&self) -> LogRow {
        *self.row()
    }

    fn stop(&mut self) {}
}

/// Compares each period's replayed reference (an integrity check) and controller output
/// (counted) with the log's.
struct Compare<'a> {
    path: &'a Path,
    report: ReplayReport,
    broken: Option<RigError>,
}

impl<'a> Recorder<Supervised<LogPlayer<'a>>, MuscleStep> for Compare<'a> {
    fn record(&mut self, p: &Period<'_, Supervised<LogPlayer<'a>>, MuscleStep>) {
        let row = p.truth;
        let r = &p.output.reference;
        if self.broken.is_none() {
            for (name, logged, replayed) in [
                ("reference_m", row.reference.position_m, r.position_m),
                (
                    "reference_velocity_m_s",
                    row.reference.velocity_m_s,
                    r.velocity_m_s,
                ),
                (
                    "reference_acceleration_m_s2",
                    row.reference.acceleration_m_s2,
                    r.acceleration_m_s2,
                ),
            ] {
                if let Err(e) = exact(self.path, row, name, logged, replayed) {
                    self.broken = Some(e);
                    break;
                }
            }
        }
        let c = &p.output.control;
        let d = &c.diagnostics;
        let replayed = [
            c.pressure_cmd_pa,
            d.velocity_m_s,
            d.proxy_position_m,
            d.s_p,
            d.s_q,
            d.gain_hat,
            d.disturbance_hat,
        ];
        if replayed
            .iter()
            .zip(&row.control)
            .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            self.report.mismatches += 1;
            let diff = (c.pressure_cmd_pa - row.control[0]).abs();
            if diff.is_finite() {
                self.report.max_abs_difference_pa = self.report.max_abs_difference_pa.max(diff);
            }
        }
        self.report.periods += 1;
    }
}

/// The log's header and rows, once its digest has been checked.
fn read_checked(path: &Path) -> Result<(Header, Rows), RigError> {
    let text = std::fs::read_to_string(path).map_err(|e| RigError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    let header = parse_header(path, &header_lines(&text))?;
    let (body, digest_rows) = check_digest(path, &text)?;
    let rows = parse_rows(path, body, digest_rows)?;
    Ok((header, rows))
}

/// What [`verify`] found in a log that can be trusted.
#[derive(Debug, Clone, PartialEq)]
pub struct VerifiedLog {
    /// The rig's configuration, from the header (checked as `rig run` checks it).
    pub config: RigConfig,
    /// Control period rows between the activation and the vent.
    pub periods: usize,
    /// The fault the run ended with (`interrupted` for a signal), if any.
    pub fault: Option<String>,
}

/// Checks a log as replay does before trusting it, without replaying the controller: its
/// header (this version's, with a configuration `rig run` would accept), its digest (not
/// truncated, not edited), and rows that run from the activation through contiguous
/// periods to the vent row. For readers of a log's data (identification).
pub fn verify(path: &Path) -> Result<VerifiedLog, RigError> {
    let (header, rows) = read_checked(path)?;
    exact(
        path,
        &rows.activation,
        "period",
        rows.activation.period,
        0.0,
    )?;
    for (k, row) in rows.periods.iter().enumerate() {
        exact(path, row, "period", row.period, (k + 1) as f64)?;
    }
    check_vent(path, &rows)?;
    Ok(VerifiedLog {
        config: header.config,
        periods: rows.periods.len(),
        fault: rows.fault,
    })
}

/// Replays `path`.
pub fn replay(path: &Path) -> Result<ReplayReport, RigError> {
    let (header, rows) = read_checked(path)?;
    let player = LogPlayer {
        path,
        header: &header,
        rows: &rows,
        at: None,
        elapsed: 0,
    };
    // The rig's supervisor, without its watchdog: it clamps and rate-limits the replayed
    // commands as it did on the rig.
    let mut limits = header.config.supervisor_limits();
    limits.watchdog_periods = 0;
    let mut rig = Supervised::new(player, limits, None);
    let controller = header
        .config
        .controller_for(&header.gains, header.excitation.as_ref())?;
    let controller_name = controller.name().to_owned();
    let mut task = MuscleTask::new(controller, &header.reference);
    let mut compare = Compare {
        path,
        report: ReplayReport {
            log: path.display().to_string(),
            controller: controller_name,
            periods: 0,
            max_abs_difference_pa: 0.0,
            mismatches: 0,
            fault: rows.fault.clone(),
        },
        broken: None,
    };
    let elapsed: f64 = rows
        .periods
        .iter()
        .map(|r| (r.dt_s / header.config.period_s).round())
        .sum();
    if !rows.periods.is_empty() {
        let settings = LoopSettings::new(elapsed * header.config.period_s)?;
        let outcome = pma_loop::run(&mut rig, &mut task, &mut compare, &settings)?;
        if let End::Fault { error, .. } = outcome.end {
            return Err(match error {
                Fault::Backend(e) => e,
                other => log_error(
                    path,
                    format!("the rig's supervisor would have stopped here: {other}"),
                ),
            });
        }
    }
    if let Some(e) = compare.broken {
        return Err(e);
    }
    check_vent(path, &rows)?;
    Ok(compare.report)
}

/// The vent row closes the last period: same time, the next number, zero pressure.
fn check_vent(path: &Path, rows: &Rows) -> Result<(), RigError> {
    let last = rows.periods.last().unwrap_or(&rows.activation);
    let v = &rows.vent;
    exact(path, v, "period", v.period, last.period + 1.0)?;
    exact(path, v, "t_s", v.t_s, last.t_s)?;
    exact(path, v, "valve_cmd_pa", v.valve_cmd_pa, 0.0)
}
