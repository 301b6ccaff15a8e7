//! The composition of `pma-exo paper`: which controllers and gains every experiment runs.
use super::{AmplitudeRow, ComparisonRow, Entry, LoadStepRow, MpRow, Series};
use crate::StudyError;
use pma_bench::{PlantConfig, RunSpec};
use pma_control::{AprcGains, ControllerConfig, ControllerKind, SineReference};
use serde::Serialize;

/// What the runs of a plot differ in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Varied {
    /// The controller or its gains: errors can differ by decades.
    Controller,
    /// One setting of a single controller (proxy mass, amplitude, load).
    Setting,
    /// A model against a measurement (identification): each series' `reference_m` is the
    /// measured position, its `position_m` the model's.
    Model,
}

/// A plot of `paper`: its runs and what a reader needs to read them.
#[derive(Debug, Clone)]
pub struct Plot {
    /// File stem.
    pub name: &'static str,
    /// First title line: the experiment.
    pub title: String,
    /// Second title line: reference, plant, duration and period.
    pub setting: String,
    /// Heading of the legend: what the runs differ in, with its unit.
    pub legend_title: String,
    /// What the runs differ in.
    pub varied: Varied,
    /// Instants marked on the time axis (s), with their label.
    pub events: Vec<(f64, String)>,
    /// One series per run.
    pub series: Vec<Series>,
}

/// One budget of the equal-activity comparison: its five gain files, embedded.
macro_rules! activity_budget {
    ($bar_per_s:literal, $dir:literal) => {
        (
            $bar_per_s,
            [
                activity_budget!(@file $dir, "aprc-ndo"),
                activity_budget!(@file $dir, "ndo-smc"),
                activity_budget!(@file $dir, "psmc"),
                activity_budget!(@file $dir, "sta"),
                activity_budget!(@file $dir, "pid"),
            ],
        )
    };
    (@file $dir:literal, $name:literal) => {
        (
            $name,
            include_str!(concat!(
                "../../models/gains/equal-activity/",
                $dir,
                "/",
                $name,
                ".toml"
            )),
        )
    };
}

/// A budget of the equal-activity comparison: bar/s and the five controllers' gain files.
type ActivityBudget = (f64, [(&'static str, &'static str); 5]);

/// The equal-activity comparison (`crates/pma-studies/models/gains/equal-activity/README.md`): every
/// controller tuned under the same budget on command activity.
const EQUAL_ACTIVITY: [ActivityBudget; 3] = [
    activity_budget!(1.5, "1.5"),
    activity_budget!(3.0, "3"),
    activity_budget!(6.0, "6"),
];

/// The gain file of `controller` tuned within `budget` bar/s (`"1.5"`, `"3"`, `"6"`), if
/// the comparison has one; APRC (the ablation) runs APRC-NDO's.
pub(crate) fn equal_activity_file(budget: &str, controller: &str) -> Option<&'static str> {
    let b: f64 = budget.parse().ok()?;
    let name = if controller == "aprc" {
        "aprc-ndo"
    } else {
        controller
    };
    EQUAL_ACTIVITY
        .iter()
        .find(|(bar, _)| *bar == b)?
        .1
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| *text)
}

/// APRC-NDO's gains tuned like the baselines (`crates/pma-control/models/gains/`).
pub(crate) fn aprc_ndo_tuned() -> &'static str {
    pma_control::shipped::APRC_NDO_TUNED
}

/// One budget of the equal-activity comparison.
#[derive(Debug, Serialize)]
pub struct ActivityTable {
    /// Budget on the mean |du/dt| of the command during tuning (bar/s).
    pub budget_bar_per_s: f64,
    /// The sine (the tuning reference).
    pub sine: Vec<ComparisonRow>,
    /// The chirp, same gains.
    pub chirp: Vec<ComparisonRow>,
}

/// The entries of one budget: APRC-NDO, its ablation with the same gains, the baselines.
pub fn activity_entries(budget: &ActivityBudget) -> Result<Vec<Entry>, StudyError> {
    let label = format!("{} bar/s", budget.0);
    let mut v = Vec::with_capacity(6);
    for (name, text) in budget.1 {
        let cfg = ControllerConfig::from_toml_str(text)?;
        if let ControllerConfig::AprcNdo(g) = cfg {
            v.push((name.to_owned(), label.clone(), cfg));
            v.push(("aprc".to_owned(), label.clone(), ControllerConfig::Aprc(g)));
        } else {
            v.push((name.to_owned(), label.clone(), cfg));
        }
    }
    Ok(v)
}

/// Runs the equal-activity comparison; the plot is the sine at the middle budget.
pub fn equal_activity(
    plant: &PlantConfig,
    spec: &RunSpec,
) -> Result<(Vec<ActivityTable>, Vec<Series>), StudyError> {
    let mut tables = Vec::with_capacity(EQUAL_ACTIVITY.len());
    let mut plotted = Vec::new();
    for (k, budget) in EQUAL_ACTIVITY.iter().enumerate() {
        let e = activity_entries(budget)?;
        let (sine, s_sine) = super::comparison(&e, plant, &SineReference::paper(), spec)?;
        let (chirp, _) = super::comparison(&e, plant, &super::chirp(), spec)?;
        if k == 1 {
            plotted = s_sine;
        }
        tables.push(ActivityTable {
            budget_bar_per_s: budget.0,
            sine,
            chirp,
        });
    }
    Ok((tables, plotted))
}

/// Fixed adaptive gain of the `m_p` sweep: about what the adaptive law (10) reaches after
/// 20 s of the sine on the `mismatch` plant with the paper's gains.
pub const MP_SWEEP_GAIN: f64 = 1.0;

/// Everything `paper` computes.
#[derive(Debug, Serialize)]
pub struct PaperResults {
    /// Plant preset used.
    pub plant: String,
    /// Seconds per run.
    pub duration_s: f64,
    /// Table II: sine.
    pub table2: Vec<ComparisonRow>,
    /// Fig. 7: chirp.
    pub chirp: Vec<ComparisonRow>,
    /// Fig. 4: proxy mass sweep.
    pub mp_sweep: Vec<MpRow>,
    /// Fig. 5: amplitudes.
    pub amplitudes: Vec<AmplitudeRow>,
    /// Fig. 8: load steps.
    pub load_step: Vec<LoadStepRow>,
    /// Table II and the chirp again, every controller tuned under the same budget on
    /// command activity (not in the paper; see [`ActivityTable`]).
    pub equal_activity: Vec<ActivityTable>,
}

/// The controllers of Table II: APRC-NDO and its ablation with the paper's gains and
/// tuned, and the four baselines with their tuned defaults.
pub fn entries() -> Result<Vec<Entry>, StudyError> {
    let tuned_gains = match ControllerConfig::from_toml_str(aprc_ndo_tuned())? {
        ControllerConfig::AprcNdo(g) => g,
        other => {
            return Err(pma_control::ConfigError::WrongController {
                requested: ControllerKind::AprcNdo,
                found: other.kind(),
            }
            .into())
        }
    };
    let mut v: Vec<Entry> = vec![
        (
            "aprc-ndo".into(),
            "paper".into(),
            ControllerConfig::AprcNdo(AprcGains::PAPER),
        ),
        (
            "aprc".into(),
            "paper".into(),
            ControllerConfig::Aprc(AprcGains::PAPER),
        ),
        (
            "aprc-ndo".into(),
            "tuned".into(),
            ControllerConfig::AprcNdo(tuned_gains),
        ),
        (
            "aprc".into(),
            "tuned".into(),
            ControllerConfig::Aprc(tuned_gains),
        ),
    ];
    for k in [
        ControllerKind::Psmc,
        ControllerKind::NdoSmc,
        ControllerKind::Sta,
        ControllerKind::Pid,
    ] {
        v.push((k.as_str().into(), "tuned".into(), k.default_config()));
    }
    Ok(v)
}

/// Runs all experiments on `plant`.
pub fn compute(
    plant: &PlantConfig,
    spec: &RunSpec,
) -> Result<(PaperResults, Vec<Plot>), StudyError> {
    let e = entries()?;
    let (table2, s_table2) = super::comparison(&e, plant, &SineReference::paper(), spec)?;
    let (chirp, s_chirp) = super::comparison(&e, plant, &super::chirp(), spec)?;
    let (mp_sweep, s_mp) = super::mp_sweep(AprcGains::PAPER, MP_SWEEP_GAIN, plant, spec)?;
    let paper_cfg = ControllerConfig::AprcNdo(AprcGains::PAPER);
    let (amplitudes, s_amp) = super::amplitudes(&paper_cfg, plant, spec)?;
    let (load_step, s_load) = super::load_step(&paper_cfg, plant, spec)?;
    let (equal_activity, s_activity) = equal_activity(plant, spec)?;
    let plots = plots(
        plant,
        spec,
        [s_table2, s_chirp, s_mp, s_amp, s_load, s_activity],
    );
    Ok((
        PaperResults {
            plant: plant.name.clone(),
            duration_s: spec.duration_s,
            table2,
            chirp,
            mp_sweep,
            amplitudes,
            load_step,
            equal_activity,
        },
        plots,
    ))
}

/// The six plots, in the order of `compute`'s series: table2, chirp, m_p sweep,
/// amplitudes, load step, equal activity.
fn plots(plant: &PlantConfig, spec: &RunSpec, series: [Vec<Series>; 6]) -> Vec<Plot> {
    let sine = SineReference::paper();
    let sine_text = format!(
        "sine {} Hz, A = B = {} mm",
        sine.frequency_hz,
        sine.amplitude_m * 1e3
    );
    let setting = |reference: &str| {
        format!(
            "{reference}; {} plant, {} s per run at {} ms",
            plant.name,
            spec.duration_s,
            spec.period_s * 1e3
        )
    };
    let chirp = super::chirp();
    let chirp_text = format!(
        "chirp {} to {} Hz in {} s, A = B = {} mm",
        chirp.f0_hz,
        chirp.f1_hz,
        chirp.sweep_s,
        chirp.amplitude_m * 1e3
    );
    let [s_table2, s_chirp, s_mp, s_amp, s_load, s_activity] = series;
    let plot = |name, title: String, setting: String, legend_title: &str, varied, series| Plot {
        name,
        title,
        setting,
        legend_title: legend_title.to_owned(),
        varied,
        events: Vec::new(),
        series,
    };
    vec![
        plot(
            "table2",
            "Table II: the controllers on the sine".to_owned(),
            setting(&sine_text),
            "controller (gains)",
            Varied::Controller,
            s_table2,
        ),
        plot(
            "chirp",
            "Fig. 7: the controllers on the chirp".to_owned(),
            setting(&chirp_text),
            "controller (gains)",
            Varied::Controller,
            s_chirp,
        ),
        plot(
            "mp_sweep",
            format!(
                "Fig. 4: APRC-NDO (paper gains), adaptive gain held at {MP_SWEEP_GAIN}, proxy mass m_p"
            ),
            setting(&sine_text),
            "proxy mass m_p\n(dimensionless, eq. 11)",
            Varied::Setting,
            s_mp,
        ),
        plot(
            "amplitudes",
            "Fig. 5: APRC-NDO (paper gains) on sines of several amplitudes".to_owned(),
            setting(&format!("sine {} Hz, offset B = A", sine.frequency_hz)),
            "sine amplitude A",
            Varied::Setting,
            s_amp,
        ),
        Plot {
            events: vec![(super::LOAD_STEP_TIME_S, "load added".to_owned())],
            ..plot(
                "load_step",
                format!(
                    "Fig. 8: APRC-NDO (paper gains), load added at {} s",
                    super::LOAD_STEP_TIME_S
                ),
                setting(&sine_text),
                "added load",
                Varied::Setting,
                s_load,
            )
        },
        plot(
            "equal_activity",
            format!(
                "Not in the paper: every controller tuned within {} bar/s of command activity",
                EQUAL_ACTIVITY[1].0
            ),
            setting(&sine_text),
            "controller (budget)",
            Varied::Controller,
            s_activity,
        ),
    ]
}
