//! What ran: every JSON object, summary, CSV header comment, report and Rerun recording
//! names the program and its version, the command line, and the run's inputs (scenario or
//! plant, controller, gain source, patient preset, seed), so that an output found later
//! says how to make it again.
use serde::Serialize;

/// The provenance of one run; `None` where a field does not apply (a bench run has no
/// patient).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Provenance {
    /// `pma-exo <version>`.
    pub program: String,
    /// The command line, quoted for a POSIX shell.
    pub command: String,
    /// Scenario (leg runs).
    pub scenario: Option<String>,
    /// Plant preset or file (bench and rig runs).
    pub plant: Option<String>,
    /// Controller.
    pub controller: Option<String>,
    /// Where the gains came from: a file, `paper`, `scenario`, `shipped leg gains`, ...
    pub gains: Option<String>,
    /// Patient preset (`passive`, the scenario's, a spasticity preset).
    pub patient: Option<String>,
    /// Seed of the run's random parts (noise, spasms), if any.
    pub seed: Option<u64>,
}

/// `arg` quoted for a POSIX shell when it needs it.
fn quoted(arg: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./=:,@+%".contains(c);
    if !arg.is_empty() && arg.chars().all(plain) {
        arg.to_owned()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

impl Provenance {
    /// This process: the program, its version and its command line.
    pub fn of_this_run() -> Self {
        let mut args = std::env::args();
        let _ = args.next();
        let command = std::iter::once("pma-exo".to_owned())
            .chain(args.map(|a| quoted(&a)))
            .collect::<Vec<_>>()
            .join(" ");
        Self {
            program: format!("pma-exo {}", env!("CARGO_PKG_VERSION")),
            command,
            ..Self::default()
        }
    }

    /// One line: `pma-exo 0.1.0, `pma-exo simulate ...`: scenario ..., controller ...`.
    pub fn line(&self) -> String {
        let mut parts = Vec::new();
        let mut push = |name: &str, v: &Option<String>| {
            if let Some(v) = v {
                parts.push(format!("{name} {v}"));
            }
        };
        push("scenario", &self.scenario);
        push("plant", &self.plant);
        push("controller", &self.controller);
        push("gains", &self.gains);
        push("patient", &self.patient);
        if let Some(s) = self.seed {
            parts.push(format!("seed {s}"));
        }
        format!(
            "{}, `{}`: {}",
            self.program,
            self.command,
            if parts.is_empty() {
                "-".to_owned()
            } else {
                parts.join(", ")
            }
        )
    }

    /// `report` as a JSON object with a `provenance` member.
    pub fn attach(&self, report: &impl Serialize) -> serde_json::Result<serde_json::Value> {
        let mut v = serde_json::to_value(report)?;
        if let Some(map) = v.as_object_mut() {
            map.insert("provenance".into(), serde_json::to_value(self)?);
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_names_what_ran_and_quotes_what_needs_it() {
        let p = Provenance {
            program: "pma-exo 0.1.0".into(),
            command: [
                "pma-exo",
                "simulate",
                "my scenario.toml",
                "--controller",
                "pid",
            ]
            .map(quoted)
            .join(" "),
            scenario: Some("s".into()),
            controller: Some("pid".into()),
            gains: Some("shipped leg gains".into()),
            seed: Some(7),
            ..Provenance::default()
        };
        assert_eq!(
            p.line(),
            "pma-exo 0.1.0, `pma-exo simulate 'my scenario.toml' --controller pid`: scenario s, controller pid, gains shipped leg gains, seed 7"
        );
        let v = p.attach(&serde_json::json!({"a": 1})).unwrap();
        assert_eq!(v["provenance"]["controller"], "pid");
        assert_eq!(v["provenance"]["patient"], serde_json::Value::Null);
        assert_eq!(quoted("it's"), r"'it'\''s'");
    }
}
