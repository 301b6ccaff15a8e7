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
use crate::supervisor::limit_command;
use pma_control::SmoothStart;
use pma_control::{Controller, ControllerConfig, Measurement, RefSample, Reference};
use sha2::{Digest, Sha256};
use std::path::Path;

/// Markers of the header's sections.
pub(crate) const CONFIG_BEGIN: &str = "begin config";
pub(crate) const CONFIG_END: &str = "end config";
pub(crate) const GAINS_BEGIN: &str = "begin gains";
pub(crate) const GAINS_END: &str = "end gains";
/// The header line that says where the reference started (m).
pub(crate) const REFERENCE_START: &str = "reference start_m = ";

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
    let reference = config.reference(start_m);
    Ok(Header {
        config,
        gains,
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

/// One row, parsed.
struct Row<'r> {
    record: &'r csv::StringRecord,
    number: usize,
    path: &'r Path,
}

impl Row<'_> {
    fn text(&self, c: usize) -> &str {
        self.record.get(c).unwrap_or("")
    }

    fn num(&self, c: usize) -> Result<f64, RigError> {
        let s = self.text(c);
        s.parse::<f64>().map_err(|_| {
            log_error(
                self.path,
                format!("row {}: `{s}` is not a number", self.number),
            )
        })
    }

    /// Fails unless the logged value equals the recomputed one bit for bit.
    fn exact(&self, c: usize, name: &str, expected: f64) -> Result<(), RigError> {
        let logged = self.num(c)?;
        if logged.to_bits() == expected.to_bits() {
            Ok(())
        } else {
            Err(self.differs(name, logged, expected))
        }
    }

    fn differs(&self, name: &str, logged: f64, expected: f64) -> RigError {
        log_error(
            self.path,
            format!(
                "row {}: {name} is {logged:?}, but the log's own header and earlier rows give {expected:?}: the log was edited or is not from this configuration",
                self.number
            ),
        )
    }
}

/// Replays `path`.
pub fn replay(path: &Path) -> Result<ReplayReport, RigError> {
    let text = std::fs::read_to_string(path).map_err(|e| RigError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    let header = parse_header(path, &header_lines(&text))?;
    let (body, digest_rows) = check_digest(path, &text)?;
    let mut controller = header.config.build_controller(&header.gains)?;
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_reader(body.as_bytes());
    let names = reader
        .headers()
        .map_err(|e| log_error(path, e.to_string()))?
        .clone();
    let columns = Columns::of(path, &names)?;
    let mut replay = Replayer {
        path,
        header: &header,
        columns: &columns,
        controller: controller.as_mut(),
        report: ReplayReport {
            log: path.display().to_string(),
            controller: header.gains.kind().as_str().to_owned(),
            periods: 0,
            max_abs_difference_pa: 0.0,
            mismatches: 0,
            fault: None,
        },
        state: None,
    };
    let mut rows = 0u64;
    for (i, record) in reader.records().enumerate() {
        let record = record.map_err(|e| log_error(path, e.to_string()))?;
        replay.row(&Row {
            record: &record,
            number: i + 1,
            path,
        })?;
        rows += 1;
    }
    if rows != digest_rows {
        return Err(log_error(
            path,
            format!("{rows} rows, but the digest line says {digest_rows}"),
        ));
    }
    match replay.state {
        Some(State { vented: true, .. }) => Ok(replay.report),
        Some(_) => Err(log_error(
            path,
            "no vent row at the end: the log is incomplete",
        )),
        None => Err(log_error(path, "no activation row: nothing to replay")),
    }
}

/// Where the replay stands.
struct State {
    period: u64,
    elapsed: u64,
    t0: f64,
    t: f64,
    valve_cmd_pa: f64,
    vented: bool,
}

struct Replayer<'a> {
    path: &'a Path,
    header: &'a Header,
    columns: &'a Columns,
    controller: &'a mut dyn Controller,
    report: ReplayReport,
    state: Option<State>,
}

impl Replayer<'_> {
    fn row(&mut self, row: &Row<'_>) -> Result<(), RigError> {
        let c = self.columns;
        if self.state.as_ref().is_some_and(|s| s.vented) {
            return Err(log_error(
                self.path,
                format!("row {}: a row after the vent row", row.number),
            ));
        }
        let event = row.text(c.event).to_owned();
        let fault = row.text(c.fault);
        if event != "vent" && !fault.is_empty() {
            return Err(log_error(
                self.path,
                format!(
                    "row {}: a fault (`{fault}`) outside the vent row",
                    row.number
                ),
            ));
        }
        match (event.as_str(), self.state.is_some()) {
            ("activate", false) => self.activate(row),
            ("", true) => self.period(row),
            ("vent", true) => self.vent(row),
            ("activate", true) => Err(log_error(
                self.path,
                format!("row {}: a second activation", row.number),
            )),
            ("", false) | ("vent", false) => Err(log_error(
                self.path,
                format!("row {}: a row before the activation row", row.number),
            )),
            (other, _) => Err(log_error(
                self.path,
                format!("row {}: unknown event `{other}`", row.number),
            )),
        }
    }

    /// The position the sensor's volts give, checked against the logged one.
    fn measurement(&self, row: &Row<'_>) -> Result<Measurement, RigError> {
        let c = self.columns;
        let position_m = self
            .header
            .config
            .calibration
            .position_m(row.num(c.position_v)?);
        row.exact(c.position, "position_m", position_m)?;
        Ok(Measurement { position_m })
    }

    fn reference(&self, row: &Row<'_>, t: f64) -> Result<RefSample, RigError> {
        let r = self.header.reference.sample(t);
        let [p, v, a] = self.columns.reference;
        row.exact(p, "reference_m", r.position_m)?;
        row.exact(v, "reference_velocity_m_s", r.velocity_m_s)?;
        row.exact(a, "reference_acceleration_m_s2", r.acceleration_m_s2)?;
        Ok(r)
    }

    fn check_valve_v(&self, row: &Row<'_>, valve_cmd_pa: f64) -> Result<(), RigError> {
        let expected = self.header.config.calibration.valve_v(valve_cmd_pa);
        let logged = row.num(self.columns.valve_v)?;
        if (logged - expected).abs() > VOLTS_TOLERANCE {
            return Err(row.differs("valve_v", logged, expected));
        }
        Ok(())
    }

    fn activate(&mut self, row: &Row<'_>) -> Result<(), RigError> {
        let c = self.columns;
        row.exact(c.period, "period", 0.0)?;
        let t0 = row.num(c.t)?;
        let measurement = self.measurement(row)?;
        let reference = self.reference(row, t0)?;
        let valve_cmd_pa = row.num(c.valve_cmd)?;
        self.check_valve_v(row, valve_cmd_pa)?;
        self.controller.reset(measurement, reference);
        self.state = Some(State {
            period: 0,
            elapsed: 0,
            t0,
            t: t0,
            valve_cmd_pa,
            vented: false,
        });
        Ok(())
    }

    fn period(&mut self, row: &Row<'_>) -> Result<(), RigError> {
        let c = self.columns;
        let period_s = self.header.config.period_s;
        let Some(s) = self.state.as_mut() else {
            return Ok(());
        };
        let period = s.period + 1;
        row.exact(c.period, "period", period as f64)?;
        let dt = row.num(c.dt)?;
        let n = (dt / period_s).round();
        if !(n >= 1.0 && f64::from(n as u32) * period_s == dt) {
            return Err(row.differs("dt_s", dt, period_s));
        }
        let elapsed = s.elapsed + n as u64;
        let t = s.t0 + elapsed as f64 * period_s;
        row.exact(c.t, "t_s", t)?;
        let last_valve_cmd = s.valve_cmd_pa;
        let measurement = self.measurement(row)?;
        let reference = self.reference(row, t)?;
        let out = self.controller.update(&reference, &measurement, dt);
        let logged = row.num(c.command)?;
        let limits = &self.header.config.limits;
        let valve_cmd_pa = limit_command(logged, last_valve_cmd, limits, period_s);
        row.exact(c.valve_cmd, "valve_cmd_pa", valve_cmd_pa)?;
        self.check_valve_v(row, valve_cmd_pa)?;
        self.controller.applied(valve_cmd_pa);
        let d = &out.diagnostics;
        let replayed = [
            out.pressure_cmd_pa,
            d.velocity_m_s,
            d.proxy_position_m,
            d.s_p,
            d.s_q,
            d.gain_hat,
            d.disturbance_hat,
        ];
        let mut logged_states = [logged, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        logged_states[1] = row.num(c.velocity)?;
        for (slot, &col) in logged_states[2..].iter_mut().zip(&c.states) {
            *slot = row.num(col)?;
        }
        if replayed
            .iter()
            .zip(&logged_states)
            .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            self.report.mismatches += 1;
            let diff = (out.pressure_cmd_pa - logged).abs();
            if diff.is_finite() {
                self.report.max_abs_difference_pa = self.report.max_abs_difference_pa.max(diff);
            }
        }
        self.report.periods += 1;
        if let Some(s) = self.state.as_mut() {
            s.period = period;
            s.elapsed = elapsed;
            s.t = t;
            s.valve_cmd_pa = valve_cmd_pa;
        }
        Ok(())
    }

    fn vent(&mut self, row: &Row<'_>) -> Result<(), RigError> {
        let c = self.columns;
        let Some(s) = self.state.as_mut() else {
            return Ok(());
        };
        row.exact(c.period, "period", (s.period + 1) as f64)?;
        row.exact(c.t, "t_s", s.t)?;
        row.exact(c.valve_cmd, "valve_cmd_pa", 0.0)?;
        s.vented = true;
        let fault = row.text(c.fault);
        self.report.fault = (!fault.is_empty()).then(|| fault.to_owned());
        self.check_valve_v(row, 0.0)
    }
}
