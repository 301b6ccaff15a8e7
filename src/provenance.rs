//! What ran: every JSON object, summary, CSV header comment, report and Rerun recording
//! names the program and its version, the command line, and the run's inputs (scenario or
//! plant, controller, gain source, patient, every seed), so that an output found later
//! says how to make it again. A file is named by its path and the name written inside it
//! (two files may carry one inner name).
use serde::Serialize;
use std::collections::BTreeMap;

/// The provenance of one run; `None` where a field does not apply (a bench run has no
/// patient).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Provenance {
    /// `pma-exo <version>`.
    pub program: String,
    /// The command line, quoted for a POSIX shell.
    pub command: String,
    /// Scenario (leg runs): an embedded name, or a file's path and inner name.
    pub scenario: Option<String>,
    /// Plant preset or file (bench and rig runs).
    pub plant: Option<String>,
    /// Controller.
    pub controller: Option<String>,
    /// Where the gains came from: a file, `paper`, `scenario (APRC-NDO)`, `shipped in-air gains (...)`, ...
    pub gains: Option<String>,
    /// Patient: per joint `passive` or its parts (spasticity, spasms, effort, stiffness).
    pub patient: Option<String>,
    /// The valve model that ran (leg runs): `ideal`, a first-order lag, or a flow-limited
    /// valve with its supply and tube.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub valve: Option<String>,
    /// The seed of each random part that ran (noise, spasms, a bootstrap), by part.
    pub seeds: Seeds,
}

/// The seeds of a run's random parts, by part (`encoder noise`, `hip spasms`, ...); empty
/// when nothing random ran.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Seeds(pub BTreeMap<String, u64>);

impl Seeds {
    /// One part's seed.
    pub fn of(part: &str, seed: u64) -> Self {
        Self::default().with(part, seed)
    }

    /// These and `part`'s seed.
    pub fn with(mut self, part: &str, seed: u64) -> Self {
        self.0.insert(part.to_owned(), seed);
        self
    }

    /// The scenario's: the encoders' noise (the knee's is `seed + 1`) and each joint's
    /// random spasms, those that are on.
    pub fn of_scenario(sc: &pma_leg::Scenario) -> Self {
        let mut seeds = Self::default();
        let encoder = &sc.plant.encoder;
        if encoder.noise_rms_rad > 0.0 {
            seeds = seeds.with("encoder noise", encoder.seed);
        }
        for (joint, p) in [("hip", &sc.patient.hip), ("knee", &sc.patient.knee)] {
            if let Some(s) = p.spasms.as_ref().filter(|s| s.rate_per_min > 0.0) {
                seeds = seeds.with(&format!("{joint} spasms"), s.seed);
            }
        }
        if let Some(a) = &sc.patient.active {
            seeds = seeds.with("patient's strides", a.seed);
        }
        seeds
    }
}

/// How an input given as `arg` is named: an embedded preset by its name, a file (`*.toml`)
/// by its path and the `name` written inside it.
pub fn named(arg: &str, inner_name: &str) -> String {
    if arg.ends_with(".toml") {
        format!("{arg} (name \"{inner_name}\")")
    } else {
        arg.to_owned()
    }
}

/// `arg` quoted for a POSIX shell when it needs it; one with control characters (a
/// newline) in the `$'...'` form, so that the provenance stays one line.
fn quoted(arg: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./=:,@+%".contains(c);
    if !arg.is_empty() && arg.chars().all(plain) {
        arg.to_owned()
    } else if arg.chars().any(char::is_control) {
        let mut out = String::from("$'");
        for c in arg.chars() {
            match c {
                '\n' => out.push_str("\\n"),
                '\t' => out.push_str("\\t"),
                '\r' => out.push_str("\\r"),
                '\\' => out.push_str("\\\\"),
                '\'' => out.push_str("\\'"),
                c if c.is_control() => out.push_str(&format!("\\x{:02x}", u32::from(c))),
                c => out.push(c),
            }
        }
        out.push('\'');
        out
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
        push("valve", &self.valve);
        if !self.seeds.0.is_empty() {
            let seeds: Vec<String> = self
                .seeds
                .0
                .iter()
                .map(|(part, seed)| format!("{part} {seed}"))
                .collect();
            parts.push(format!("seeds ({})", seeds.join(", ")));
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
            seeds: Seeds::of("hip spasms", 7).with("encoder noise", 3),
            ..Provenance::default()
        };
        assert_eq!(
            p.line(),
            "pma-exo 0.1.0, `pma-exo simulate 'my scenario.toml' --controller pid`: scenario s, controller pid, gains shipped leg gains, seeds (encoder noise 3, hip spasms 7)"
        );
        let v = p.attach(&serde_json::json!({"a": 1})).unwrap();
        assert_eq!(v["provenance"]["controller"], "pid");
        assert_eq!(v["provenance"]["patient"], serde_json::Value::Null);
        assert_eq!(v["provenance"]["seeds"]["hip spasms"], 7);
        assert_eq!(quoted("it's"), r"'it'\''s'");
    }

    /// Regression: an argument with a newline split the provenance line, which starts
    /// every CSV as one `#` line.
    #[test]
    fn an_argument_with_a_newline_stays_on_one_line() {
        assert_eq!(quoted("a\nb's"), r"$'a\nb\'s'");
        assert!(!quoted("x\ry\u{1}").contains(['\r', '\u{1}']));
    }

    /// Regression: `single --plant myplant.toml` (named "realistic" inside) was reported as
    /// plant "realistic"; a file is now named by its path and its inner name.
    #[test]
    fn a_file_is_named_by_its_path_and_inner_name() {
        assert_eq!(named("realistic", "realistic"), "realistic");
        assert_eq!(
            named("my/plant.toml", "realistic"),
            "my/plant.toml (name \"realistic\")"
        );
    }
}
