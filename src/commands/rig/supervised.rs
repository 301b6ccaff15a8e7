//! What every command that moves the rig's muscle shares (`rig run`, `rig excite`, `rig
//! commission`): the wall-time bound, the added mass and the one danger message.
use crate::output;
use anyhow::{Context, Result};
use pma_rig::config::ClockMode;
use pma_rig::RigConfig;
use std::path::Path;

/// Wall time of one lockstep period of the virtual rig, log included (s): measured 4.7 us
/// (600 s run) to 6.5 us (20 s run, start-up included) with a release build on the 2-core
/// development VM (`docs/safety.md`).
const LOCKSTEP_PERIOD_S: f64 = 6.5e-6;

/// Refuses a run over an hour of wall time unless `yes`; anything but a lockstep virtual
/// run takes real time.
pub(crate) fn check_rig_wall_time(
    cfg: &RigConfig,
    duration_s: f64,
    realtime: bool,
    yes: bool,
) -> Result<()> {
    crate::commands::check_duration(duration_s)?;
    let lockstep = !realtime
        && cfg
            .virtual_rig
            .as_ref()
            .is_some_and(|v| v.clock == ClockMode::Lockstep);
    let per_period_s = if lockstep {
        LOCKSTEP_PERIOD_S
    } else {
        cfg.period_s
    };
    output::check_wall_time("this rig run", duration_s / cfg.period_s, per_period_s, yes)
}

/// The configuration with `added_kg` more hung on the load, validated (`--added-mass-kg`
/// named in the error).
pub(crate) fn with_added_mass(mut cfg: RigConfig, added_kg: f64) -> Result<RigConfig> {
    cfg.load.added_mass_kg += added_kg;
    cfg.validate().context("--added-mass-kg")?;
    Ok(cfg)
}

/// The one message a run that could not vent must print, whatever else happens.
pub(crate) fn warn_if_not_vented(report: &pma_rig::RigReport) {
    if !report.vented {
        eprintln!(
            "DANGER: the valve could not be vented at the end of the run: dump the air by hand"
        );
    }
}

/// Calls `each` with the index and the values of `columns` (NaN where a cell is not a
/// number) of every period of the rig log at `path`, the vent row left out.
pub(crate) fn for_each_period(
    path: &Path,
    columns: &[&str],
    mut each: impl FnMut(usize, &[f64]),
) -> Result<()> {
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(path)
        .with_context(|| format!("cannot read `{}`", path.display()))?;
    let names = reader.headers()?.clone();
    let col = |n: &str| {
        names
            .iter()
            .position(|c| c == n)
            .with_context(|| format!("`{}` has no `{n}` column", path.display()))
    };
    let event = col("event")?;
    let wanted = columns.iter().map(|n| col(n)).collect::<Result<Vec<_>>>()?;
    let mut values = vec![0.0; wanted.len()];
    for (k, row) in reader.records().enumerate() {
        let row = row?;
        if &row[event] == "vent" {
            continue;
        }
        for (v, &c) in values.iter_mut().zip(&wanted) {
            *v = row[c].parse().unwrap_or(f64::NAN);
        }
        each(k, &values);
    }
    Ok(())
}
