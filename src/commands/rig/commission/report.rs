//! What `rig commission` says it did: `report.md`, the plots and `--json`, each run named
//! by what actually ran (the controller, where its gains came from, what it was told).
use super::{Args, Load, Plan};
use crate::output::{self, OutFile};
use crate::say;
use anyhow::{Context, Result};
use pma_control::ControllerKind;
use pma_studies::experiments::paper::{Plot, Varied};
use pma_studies::experiments::Series;
use pma_studies::identify::{IdLog, Identified};
use std::path::{Path, PathBuf};

/// One supervised rig run of the commissioning and how it ended.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct RunResult {
    /// What ran: the controller, where its gains came from, what it was told.
    pub what: String,
    /// Its log.
    pub log: String,
    /// RTE on the measured position (%), up to the fault if the supervisor stopped it.
    pub rte_percent: f64,
    /// The supervisor's fault, if it stopped the run (vented).
    pub fault: Option<String>,
    /// The fault's message.
    pub fault_detail: Option<String>,
    /// When the supervisor stopped it (s after the activation).
    pub faulted_at_s: Option<f64>,
}

impl RunResult {
    /// The RTE of a run that completed.
    fn completed_rte(&self) -> Option<f64> {
        self.fault.is_none().then_some(self.rte_percent)
    }

    /// The report's cell for it.
    fn cell(&self) -> String {
        match &self.fault {
            None => format!("{:.3} %", self.rte_percent),
            Some(f) => format!(
                "faulted at {:.1} s: `{f}` ({}); the supervisor vented; {:.3} % up to the fault",
                self.faulted_at_s.unwrap_or(0.0),
                self.fault_detail.as_deref().unwrap_or("no detail"),
                self.rte_percent
            ),
        }
    }
}

/// What the robust tuning found (its mean over the plants).
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct Tuning {
    /// Bench runs it took.
    pub runs: usize,
    /// IAE of the best gain set (m).
    pub iae_m: f64,
    /// Its command activity (bar/s).
    pub variation_bar_per_s: f64,
    /// Whether it keeps `--max-variation` (otherwise it is not verified).
    pub within_budget: bool,
}

/// What `--json` prints and `report.md` tells, filled in stage by stage.
#[derive(serde::Serialize)]
pub(super) struct Report {
    config: String,
    controller: &'static str,
    /// The stage the operator stopped the commissioning at (SIGINT/SIGTERM), if any.
    pub interrupted_at_stage: Option<u32>,
    /// Stage 1: the controller as configured (its fault, if any, is a result).
    pub before: Option<RunResult>,
    /// Stage 4: the best gain set the robust tuning found.
    pub tuning: Option<Tuning>,
    /// Stage 5: the same gains, told the identified plant.
    pub told: Option<RunResult>,
    /// Stage 5: the robustly tuned gains, told the identified plant (none if no gain set
    /// kept the budget).
    pub tuned: Option<RunResult>,
    /// A completed run's RTE (%); null if it did not run or was stopped (see `before`,
    /// `told`, `tuned`).
    rte_before_percent: Option<f64>,
    rte_told_percent: Option<f64>,
    rte_tuned_percent: Option<f64>,
    pub rte_after_percent: Option<f64>,
    /// `tuned` or `current`: the gains written to `gains.toml`.
    pub kept: Option<&'static str>,
    pub plant: Option<PathBuf>,
    pub gains: Option<PathBuf>,
    report: Option<PathBuf>,
    pub identified: Option<Identified>,
    #[serde(skip)]
    kind: ControllerKind,
    #[serde(skip)]
    load: String,
    #[serde(skip)]
    gain_source: String,
}

impl Report {
    pub fn new(a: &Args, plan: &Plan) -> Self {
        Self {
            config: a.config.clone(),
            controller: plan.kind.as_str(),
            interrupted_at_stage: None,
            before: None,
            tuning: None,
            told: None,
            tuned: None,
            rte_before_percent: None,
            rte_told_percent: None,
            rte_tuned_percent: None,
            rte_after_percent: None,
            kept: None,
            plant: None,
            gains: None,
            report: None,
            identified: None,
            kind: plan.kind,
            load: match &plan.load {
                Load::Weighed(_) => "weighed".into(),
                Load::Added(m, _) => format!("identified: {m} kg added for the second excitation"),
            },
            gain_source: plan.gain_source.clone(),
        }
    }

    /// What ran, for every output's provenance.
    pub fn provenance(&self, a: &Args) -> crate::provenance::Provenance {
        crate::provenance::Provenance {
            plant: Some(format!("rig `{}`", a.config)),
            controller: Some(self.kind.as_str().to_owned()),
            gains: Some(match self.kept {
                Some(kept) => format!("{kept} (gains.toml)"),
                None => "none kept".into(),
            }),
            seeds: crate::provenance::Seeds::of("bootstrap and tuning", a.seed),
            ..crate::provenance::Provenance::of_this_run()
        }
    }

    fn fill_rtes(&mut self) {
        self.rte_before_percent = self.before.as_ref().and_then(RunResult::completed_rte);
        self.rte_told_percent = self.told.as_ref().and_then(RunResult::completed_rte);
        self.rte_tuned_percent = self.tuned.as_ref().and_then(RunResult::completed_rte);
    }

    /// The complete commissioning: plots, `report.md`, the summary or the JSON.
    pub fn finish(&mut self, a: &Args, dir: &Path, log: &IdLog, tuned: bool) -> Result<()> {
        self.fill_rtes();
        self.report = Some(dir.join("report.md"));
        let id = self
            .identified
            .as_ref()
            .context("no identification to report")?;
        draw_plots(dir, self.kind, id, log, tuned)?;
        let md = format!("{}\n_{}_\n", self.markdown(a), self.provenance(a).line());
        OutFile::create(&dir.join("report.md"))?.finish_with(&md)?;
        if a.json {
            say!("{}", self.provenance(a).attach(self)?);
        } else if self.kept.is_some() {
            let before = self
                .before
                .as_ref()
                .map_or(String::new(), |b| match &b.fault {
                    None => format!("RTE {:.2} % before", b.rte_percent),
                    Some(f) => format!("before: {f} at {:.1} s", b.faulted_at_s.unwrap_or(0.0)),
                });
            say!(
                "commissioned {} on `{}`: {before}, {:.2} % after ({} gains); wrote {}",
                self.kind,
                a.config,
                self.rte_after_percent.unwrap_or(f64::NAN),
                self.kept.unwrap_or("no"),
                dir.display()
            );
        }
        Ok(())
    }

    /// A commissioning the operator stopped at `stage`: `report.md` (if its directory was
    /// made) says where and what is on disk; the JSON if asked.
    pub fn interrupted(&mut self, stage: u32, a: &Args, dir: Option<&Path>) -> Result<()> {
        self.interrupted_at_stage = Some(stage);
        self.fill_rtes();
        if let Some(dir) = dir {
            self.report = Some(dir.join("report.md"));
            self.write_interrupted(a, dir, stage)?;
        }
        if a.json {
            say!("{}", self.provenance(a).attach(self)?);
        }
        Ok(())
    }

    fn write_interrupted(&self, a: &Args, dir: &Path, stage: u32) -> Result<()> {
        let mut md = format!(
            "# Commissioning of {} on `{}`: interrupted\n\n\
             Interrupted at stage {stage} by the operator (SIGINT/SIGTERM): the run under way vented, \
             no later stage ran, and no gains were kept (`gains.toml` not written).\n\n",
            self.kind, a.config
        );
        if let Some(b) = &self.before {
            md.push_str(&format!(
                "| run | what ran | RTE (measured position) |\n|---|---|---|\n| before (`before.csv`) | {} | {} |\n\n",
                b.what,
                b.cell()
            ));
        }
        md.push_str("Kept in this directory:");
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot read `{}`", dir.display()))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .collect();
        names.sort();
        for n in names {
            md.push_str(&format!(" `{n}`"));
        }
        md.push_str(&format!("\n\n_{}_\n", self.provenance(a).line()));
        OutFile::create(&dir.join("report.md"))?.finish_with(&md)
    }

    fn markdown(&self, a: &Args) -> String {
        let id = self.identified.as_ref();
        let row = |name: &str, log: &str, r: Option<&RunResult>, missing: &str| match r {
            Some(r) => format!("| {name} (`{log}`) | {} | {} |\n", r.what, r.cell()),
            None => format!("| {name} (`{log}`) | - | {missing} |\n"),
        };
        let kept = match self.kept {
            Some("tuned") => "the robustly tuned gains (`gains.toml`)".to_owned(),
            Some(_) => format!("the gains that ran before, {} (`gains.toml`)", self.gain_source),
            None => "nothing: the current gains faulted in the verification and no tuned gains did better; the rig keeps its configuration (`gains.toml` not written)".into(),
        };
        let mut md = format!(
            "# Commissioning of {} on `{}`\n\n\
             Load {} ({}). Excitation {} s (`excite.csv`{}), identification (`plant.toml`), \
             robust tuning on the identified plant and {} plants within {} % of it (`gains.toml` if it won), verification on the rig.\n\n\
             | run | what ran | RTE (measured position) |\n|---|---|---|\n{}{}{}\n\
             Kept: {kept}.\n\n![tracking](tracking.png)\n\n## Identification\n\n",
            self.kind,
            a.config,
            id.map_or("?".into(), |i| format!("{:.3} kg", i.load_mass_kg)),
            self.load,
            a.excite_duration,
            if id.is_some_and(|i| i.logs > 1) {
                ", and `excite-added-mass.csv` with the added mass"
            } else {
                ""
            },
            a.robust,
            a.spread * 100.0,
            row("before", "before.csv", self.before.as_ref(), "did not run"),
            row(
                "after, same gains",
                "after-current-gains.csv",
                self.told.as_ref(),
                "did not run"
            ),
            row(
                "after, tuned gains",
                "after-tuned-gains.csv",
                self.tuned.as_ref(),
                &match &self.tuning {
                    Some(t) => format!(
                        "not run: no gain set within {} bar/s (the best: {:.2} bar/s, IAE {:.2} mm, after {} runs; `--max-variation` lets the tuning use more valve activity)",
                        a.max_variation,
                        t.variation_bar_per_s,
                        t.iae_m * 1e3,
                        t.runs
                    ),
                    None => "not run".into(),
                }
            ),
        );
        if let Some(id) = id {
            md.push_str(&identification_md(id));
        }
        md
    }
}

/// The identification's section of `report.md`.
fn identification_md(id: &Identified) -> String {
    let mut md = format!(
        "![identification](identification.png)\n\n\
         Valve {:.2} ms + {:.2} ms dead time; held-out fit {:.2} % ({:.1} um RMS); residual {:.1} um RMS, of which sensor noise {:.1} um; \
         condition number {:.0}. {}\n\n| parameter | estimate | 95 % interval | Table I / nominal |\n|---|---|---|---|\n",
        id.valve_time_constant_s * 1e3,
        id.valve_dead_time_s * 1e3,
        id.fit_percent,
        id.rms_error_m * 1e6,
        id.residual_rms_m * 1e6,
        id.noise_rms_m * 1e6,
        id.condition_number,
        id.force_scale,
    );
    for (name, e) in &id.parameters {
        let nominal = if name.ends_with("_scale") { "1" } else { "0" };
        md.push_str(&format!(
            "| {name} | {:.4} | [{:.4}, {:.4}] | {nominal} |\n",
            e.value, e.low, e.high
        ));
    }
    for (p, q, rho) in &id.inseparable {
        md.push_str(&format!(
            "\n- not separable by these data: {p} and {q} (correlation {rho:.3})"
        ));
    }
    md.push('\n');
    md
}

/// `t_s`, `reference_m` and `position_m` of a rig log's periods, every 10th.
fn log_series(path: &Path, label: &str) -> Result<Series> {
    let mut series = Series {
        label: label.to_owned(),
        ..Series::default()
    };
    let columns = ["t_s", "reference_m", "position_m"];
    super::super::supervised::for_each_period(path, &columns, |k, v| {
        if k % 10 == 0 {
            series.t_s.push(v[0]);
            series.reference_m.push(v[1]);
            series.position_m.push(v[2]);
        }
    })?;
    Ok(series)
}

/// `tracking.png` (the rig's runs against the reference) and `identification.png` (the
/// measured excitation against the identified model, open loop).
fn draw_plots(
    dir: &Path,
    kind: ControllerKind,
    id: &Identified,
    log: &IdLog,
    tuned: bool,
) -> Result<()> {
    crate::plot::register_font()?;
    let mut runs = vec![
        log_series(&dir.join("before.csv"), "before")?,
        log_series(&dir.join("after-current-gains.csv"), "after, same gains")?,
    ];
    if tuned {
        runs.push(log_series(
            &dir.join("after-tuned-gains.csv"),
            "after, tuned gains",
        )?);
    }
    let tracking = Plot {
        name: "tracking",
        title: format!("Commissioning {kind}: the rig's measured position"),
        setting:
            "before: the configuration's nominal; after: the identified plant told (report.md)"
                .into(),
        legend_title: "run".into(),
        varied: Varied::Controller,
        events: Vec::new(),
        series: runs,
    };
    let simulated = id.simulated_position_m(log).unwrap_or_default();
    let t_s: Vec<f64> = (1..=simulated.len())
        .map(|k| k as f64 * log.period_s)
        .collect();
    let decimate = |v: &[f64]| v.iter().step_by(10).copied().collect::<Vec<f64>>();
    let held_out_s = log.duration_s() * 0.75;
    let identification = Plot {
        name: "identification",
        title: "Identification: the excitation's measured position (grey) and the identified model"
            .into(),
        setting: format!(
            "open loop from rest; fitted to {held_out_s:.0} s, held out after (fit {:.2} %)",
            id.fit_percent
        ),
        legend_title: "model".into(),
        varied: Varied::Model,
        events: vec![(held_out_s, "held out".into())],
        series: vec![Series {
            label: "identified".into(),
            t_s: decimate(&t_s),
            reference_m: decimate(&log.position_m),
            position_m: decimate(&simulated),
        }],
    };
    for plot in [tracking, identification] {
        let path = dir.join(format!("{}.png", plot.name));
        output::write_via_temp(&path, |tmp| crate::plot::draw(tmp, &plot))?;
    }
    Ok(())
}
