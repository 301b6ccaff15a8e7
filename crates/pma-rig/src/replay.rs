//! Replay: a rig log's measurements, references and periods fed back through the same
//! controller, rebuilt from the configuration and gains in the log's header. For a log
//! of the same format the commands must come out bit for bit.
use crate::config::RigConfig;
use crate::error::RigError;
use crate::log::LOG_FORMAT;
use pma_control::{ControllerConfig, Measurement, RefSample};
use std::path::Path;

/// Markers of the header's sections.
pub(crate) const CONFIG_BEGIN: &str = "begin config";
pub(crate) const CONFIG_END: &str = "end config";
pub(crate) const GAINS_BEGIN: &str = "begin gains";
pub(crate) const GAINS_END: &str = "end gains";

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
    /// Periods whose command differs in any bit.
    pub mismatches: u64,
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

/// Replays `path`.
pub fn replay(path: &Path) -> Result<ReplayReport, RigError> {
    let text = std::fs::read_to_string(path).map_err(|e| RigError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    let header: Vec<String> = text
        .lines()
        .take_while(|l| l.starts_with('#'))
        .map(|l| {
            l.strip_prefix("# ")
                .unwrap_or(l.trim_start_matches('#'))
                .to_owned()
        })
        .collect();
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
    let config_text = section(&header, CONFIG_BEGIN, CONFIG_END)
        .ok_or_else(|| log_error(path, "the header has no configuration section"))?;
    let gains_text = section(&header, GAINS_BEGIN, GAINS_END)
        .ok_or_else(|| log_error(path, "the header has no gains section"))?;
    let config = RigConfig::from_toml_str(&config_text, &format!("{} (header)", path.display()))?;
    let gains = ControllerConfig::from_toml_str(&gains_text)?;
    let mut controller = config.build_controller(&gains)?;
    let mut rows = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let names = rows
        .headers()
        .map_err(|e| log_error(path, e.to_string()))?
        .clone();
    let col = |name: &str| {
        names
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| log_error(path, format!("no column `{name}`")))
    };
    let c_valve = col("valve_cmd_pa")?;
    let (c_dt, c_x, c_r, c_v, c_a, c_cmd, c_ev, c_period) = (
        col("dt_s")?,
        col("position_m")?,
        col("reference_m")?,
        col("reference_velocity_m_s")?,
        col("reference_acceleration_m_s2")?,
        col("command_pa")?,
        col("event")?,
        col("period")?,
    );
    let mut report = ReplayReport {
        log: path.display().to_string(),
        controller: gains.kind().as_str().to_owned(),
        periods: 0,
        max_abs_difference_pa: 0.0,
        mismatches: 0,
    };
    let mut started = false;
    for row in rows.records() {
        let row = row.map_err(|e| log_error(path, e.to_string()))?;
        let num = |c: usize| -> Result<f64, RigError> {
            let s = row.get(c).unwrap_or("");
            s.parse::<f64>().map_err(|_| {
                log_error(
                    path,
                    format!(
                        "period {}: `{s}` is not a number",
                        row.get(c_period).unwrap_or("?")
                    ),
                )
            })
        };
        let reference = RefSample {
            position_m: num(c_r)?,
            velocity_m_s: num(c_v)?,
            acceleration_m_s2: num(c_a)?,
        };
        let measurement = Measurement {
            position_m: num(c_x)?,
        };
        match row.get(c_ev).unwrap_or("") {
            "activate" => {
                controller.reset(measurement, reference);
                started = true;
            }
            "" if started => {
                let out = controller.update(&reference, &measurement, num(c_dt)?);
                let logged = num(c_cmd)?;
                controller.applied(num(c_valve)?);
                let diff = (out.pressure_cmd_pa - logged).abs();
                if out.pressure_cmd_pa.to_bits() != logged.to_bits() {
                    report.mismatches += 1;
                    report.max_abs_difference_pa = report.max_abs_difference_pa.max(diff);
                }
                report.periods += 1;
            }
            "" => return Err(log_error(path, "a period before the activation row")),
            _ => {}
        }
    }
    if !started {
        return Err(log_error(path, "no activation row: nothing to replay"));
    }
    Ok(report)
}
