//! The composition of `pma-exo paper`: which controllers and gains every experiment runs.
use super::{AmplitudeRow, ComparisonRow, Entry, LoadStepRow, MpRow, Series};
use crate::{PlantConfig, RunSpec, SimError};
use pma_control::{AprcGains, ControllerConfig, ControllerKind, SineReference};
use serde::Serialize;

/// A plot: file stem, title, series.
pub type Plot = (&'static str, String, Vec<Series>);

/// APRC-NDO tuned with the same optimiser and budget as the baselines.
const APRC_NDO_TUNED: &str = include_str!("../../../../models/gains/aprc-ndo-tuned.toml");

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
}

/// The controllers of Table II: APRC-NDO and its ablation with the paper's gains and
/// tuned, and the four baselines with their tuned defaults.
pub fn entries() -> Result<Vec<Entry>, SimError> {
    let tuned_gains = match ControllerConfig::from_toml_str(APRC_NDO_TUNED)? {
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
pub fn compute(plant: &PlantConfig, spec: &RunSpec) -> Result<(PaperResults, Vec<Plot>), SimError> {
    let e = entries()?;
    let (table2, s_table2) = super::comparison(&e, plant, &SineReference::paper(), spec)?;
    let (chirp, s_chirp) = super::comparison(&e, plant, &super::chirp(), spec)?;
    let (mp_sweep, s_mp) = super::mp_sweep(AprcGains::PAPER, MP_SWEEP_GAIN, plant, spec)?;
    let paper_cfg = ControllerConfig::AprcNdo(AprcGains::PAPER);
    let (amplitudes, s_amp) = super::amplitudes(&paper_cfg, plant, spec)?;
    let (load_step, s_load) = super::load_step(&paper_cfg, plant, spec)?;
    let plots = vec![
        (
            "table2",
            format!("Sine 0.25 Hz, {} plant", plant.name),
            s_table2,
        ),
        (
            "chirp",
            format!("Chirp 0.1-0.5 Hz, {} plant", plant.name),
            s_chirp,
        ),
        (
            "mp_sweep",
            format!("APRC-NDO, fixed gain {MP_SWEEP_GAIN}, proxy masses"),
            s_mp,
        ),
        (
            "amplitudes",
            "APRC-NDO (paper gains), amplitudes".to_owned(),
            s_amp,
        ),
        (
            "load_step",
            "APRC-NDO (paper gains), load added at 10 s".to_owned(),
            s_load,
        ),
    ];
    Ok((
        PaperResults {
            plant: plant.name.clone(),
            duration_s: spec.duration_s,
            table2,
            chirp,
            mp_sweep,
            amplitudes,
            load_step,
        },
        plots,
    ))
}
