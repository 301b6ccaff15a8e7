//! The paper's experiments (Section IV), rerun on the simulated bench.
//!
//! Every experiment runs at the paper's 1 ms period for 20 s on a plant preset
//! (`mismatch` by default: the paper's controllers used Table I on a muscle it does not
//! describe exactly). Rows are plain serialisable structs; [`Series`] keep a decimated
//! time series of each run for plotting.

use crate::StudyError;
use pma_bench::{run_single, PlantConfig, RunSpec, Sample, Samples};
use pma_control::{AprcGains, ChirpReference, ControllerConfig, Reference, SineReference};
use serde::Serialize;

pub mod paper;

/// A decimated time series of one run (every 10 ms).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Time (s).
    pub t_s: Vec<f64>,
    /// Reference (m).
    pub reference_m: Vec<f64>,
    /// True position (m).
    pub position_m: Vec<f64>,
}

const DECIMATE: usize = 10;

fn run_recorded(
    label: &str,
    config: &ControllerConfig,
    plant: &PlantConfig,
    reference: &dyn Reference,
    spec: &RunSpec,
    mut on_sample: impl FnMut(&Sample),
) -> Result<(pma_bench::RunResult, Series), StudyError> {
    let mut series = Series {
        label: label.to_owned(),
        ..Series::default()
    };
    let mut k = 0usize;
    let mut observe = |s: &Sample| {
        on_sample(s);
        if k.is_multiple_of(DECIMATE) {
            series.t_s.push(s.t_s);
            series.reference_m.push(s.reference_m);
            series.position_m.push(s.position_m);
        }
        k += 1;
    };
    let res = run_single(config, plant, reference, spec, &mut Samples(&mut observe))?;
    Ok((res, series))
}

/// One controller's line in Table II (or its chirp counterpart).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComparisonRow {
    /// Controller name.
    pub controller: String,
    /// Where the gains come from: `paper` or `tuned` (firefly, same budget for all).
    pub gains: String,
    /// MAE, eq. (51) (m).
    pub mae_m: f64,
    /// IAE, eq. (52) (m).
    pub iae_m: f64,
    /// RTE, eq. (53) (%).
    pub rte_percent: f64,
    /// Total variation of the pressure command per second (bar/s).
    pub command_variation_bar_per_s: f64,
}

/// A controller entry of a comparison: name, gain source, configuration.
pub type Entry = (String, String, ControllerConfig);

/// Runs each entry on `reference` and returns Table II-style rows.
pub fn comparison(
    entries: &[Entry],
    plant: &PlantConfig,
    reference: &dyn Reference,
    spec: &RunSpec,
) -> Result<(Vec<ComparisonRow>, Vec<Series>), StudyError> {
    let mut rows = Vec::with_capacity(entries.len());
    let mut series = Vec::with_capacity(entries.len());
    for (name, gains, cfg) in entries {
        let (res, s) = run_recorded(
            &format!("{name} ({gains})"),
            cfg,
            plant,
            reference,
            spec,
            |_| {},
        )?;
        rows.push(ComparisonRow {
            controller: name.clone(),
            gains: gains.clone(),
            mae_m: res.stats.mae_m,
            iae_m: res.stats.iae_m,
            rte_percent: res.stats.rte_percent,
            command_variation_bar_per_s: res.command_variation_pa_per_s / 1e5,
        });
        series.push(s);
    }
    Ok((rows, series))
}

/// One proxy mass of the Fig. 4 / Corollary 1 sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MpRow {
    /// Proxy mass.
    pub m_p: f64,
    /// IAE (m).
    pub iae_m: f64,
    /// Standard deviation of `S_q` after the first 2 s (m/s).
    pub sq_std: f64,
    /// Largest `|S_p|` after the first 2 s (m/s).
    pub sp_max: f64,
}

/// The paper's proxy masses.
pub const PROXY_MASSES: [f64; 5] = [0.5, 1.0, 5.0, 10.0, 15.0];

/// APRC-NDO with a fixed adaptive gain (`gamma = 0`, `Gamma_hat = gain`) for each proxy
/// mass, on the sine.
pub fn mp_sweep(
    base: AprcGains,
    fixed_gain: f64,
    plant: &PlantConfig,
    spec: &RunSpec,
) -> Result<(Vec<MpRow>, Vec<Series>), StudyError> {
    let mut rows = Vec::new();
    let mut all = Vec::new();
    for m_p in PROXY_MASSES {
        let g = AprcGains {
            proxy_mass: m_p,
            gamma: 0.0,
            gain_initial: fixed_gain,
            ..base
        };
        let (mut n, mut sum, mut sum2, mut sp_max) = (0usize, 0.0, 0.0, 0.0f64);
        let (res, s) = run_recorded(
            &format!("m_p = {m_p}"),
            &ControllerConfig::AprcNdo(g),
            plant,
            &SineReference::paper(),
            spec,
            |smp| {
                if smp.t_s > 2.0 {
                    let q = smp.diagnostics.s_q;
                    n += 1;
                    sum += q;
                    sum2 += q * q;
                    sp_max = sp_max.max(smp.diagnostics.s_p.abs());
                }
            },
        )?;
        let mean = sum / n.max(1) as f64;
        rows.push(MpRow {
            m_p,
            iae_m: res.stats.iae_m,
            sq_std: (sum2 / n.max(1) as f64 - mean * mean).max(0.0).sqrt(),
            sp_max,
        });
        all.push(s);
    }
    Ok((rows, all))
}

/// One amplitude of the Fig. 5 experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AmplitudeRow {
    /// Sine amplitude `A` (offset `B = A`, so the muscle runs over `0..2A`) (m).
    pub amplitude_m: f64,
    /// MAE (m).
    pub mae_m: f64,
    /// IAE (m).
    pub iae_m: f64,
    /// RTE with `x_a = 2A` (%).
    pub rte_percent: f64,
}

/// The amplitudes run (m).
pub const AMPLITUDES_M: [f64; 4] = [0.005, 0.010, 0.015, 0.020];

/// The same controller on sines of several amplitudes, gains unchanged.
pub fn amplitudes(
    config: &ControllerConfig,
    plant: &PlantConfig,
    spec: &RunSpec,
) -> Result<(Vec<AmplitudeRow>, Vec<Series>), StudyError> {
    let mut rows = Vec::new();
    let mut all = Vec::new();
    for a in AMPLITUDES_M {
        let r = SineReference {
            amplitude_m: a,
            offset_m: a,
            ..SineReference::paper()
        };
        let (res, s) = run_recorded(
            &format!("A = {} mm", a * 1e3),
            config,
            plant,
            &r,
            spec,
            |_| {},
        )?;
        rows.push(AmplitudeRow {
            amplitude_m: a,
            mae_m: res.stats.mae_m,
            iae_m: res.stats.iae_m,
            rte_percent: res.stats.rte_percent,
        });
        all.push(s);
    }
    Ok((rows, all))
}

/// One load step of the Fig. 8 experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoadStepRow {
    /// Mass added at the step (kg).
    pub load_kg: f64,
    /// Largest `|e|` in the 5 s before the step (m).
    pub pre_step_error_m: f64,
    /// Largest `|e|` after the step (m).
    pub max_deviation_m: f64,
    /// Largest deviation of the position from the same run without the step (m): the
    /// load's own effect, separated from the ordinary tracking error.
    pub step_effect_m: f64,
    /// Time from the step until `|e|` stays under twice its pre-step level (s); `None`
    /// if it never does before the end of the run.
    pub recovery_s: Option<f64>,
}

/// The paper's added loads (kg).
pub const LOAD_STEPS_KG: [f64; 2] = [2.5, 5.0];

/// When the load is added (s).
pub const LOAD_STEP_TIME_S: f64 = 10.0;

/// Adds each load at 10 s while tracking the sine.
pub fn load_step(
    config: &ControllerConfig,
    plant: &PlantConfig,
    spec: &RunSpec,
) -> Result<(Vec<LoadStepRow>, Vec<Series>), StudyError> {
    let mut rows = Vec::new();
    let mut all = Vec::new();
    let mut unloaded = Vec::with_capacity(spec.periods()? as usize);
    run_single(
        config,
        plant,
        &SineReference::paper(),
        spec,
        &mut Samples(|smp: &Sample| unloaded.push(smp.position_m)),
    )?;
    for extra in LOAD_STEPS_KG {
        let mut p = plant.clone();
        p.load = p.load.with_step(LOAD_STEP_TIME_S, extra);
        let ts = LOAD_STEP_TIME_S;
        let mut errors: Vec<(f64, f64)> = Vec::with_capacity(spec.periods()? as usize);
        let mut step_effect = 0.0f64;
        let mut k = 0usize;
        let (_, s) = run_recorded(
            &format!("+{extra} kg at {ts} s"),
            config,
            &p,
            &SineReference::paper(),
            spec,
            |smp| {
                errors.push((smp.t_s, (smp.reference_m - smp.position_m).abs()));
                if let Some(x0) = unloaded.get(k) {
                    step_effect = step_effect.max((smp.position_m - x0).abs());
                }
                k += 1;
            },
        )?;
        let pre = errors
            .iter()
            .filter(|(t, _)| *t >= ts - 5.0 && *t < ts)
            .fold(0.0f64, |m, (_, e)| m.max(*e));
        let after = errors.iter().filter(|(t, _)| *t >= ts);
        let max_dev = after.clone().fold(0.0f64, |m, (_, e)| m.max(*e));
        let last_over = after
            .clone()
            .filter(|(_, e)| *e > 2.0 * pre)
            .map(|(t, _)| *t)
            .fold(f64::NAN, f64::max);
        let end = errors.last().map_or(ts, |(t, _)| *t);
        let recovery_s = if last_over.is_nan() {
            Some(0.0)
        } else if last_over >= end {
            None
        } else {
            Some(last_over + spec.period_s - ts)
        };
        rows.push(LoadStepRow {
            load_kg: extra,
            pre_step_error_m: pre,
            max_deviation_m: max_dev,
            step_effect_m: step_effect,
            recovery_s,
        });
        all.push(s);
    }
    Ok((rows, all))
}

/// The chirp reference of the paper.
pub fn chirp() -> ChirpReference {
    ChirpReference::paper()
}
