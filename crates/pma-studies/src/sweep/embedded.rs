//! Gain sets by name, as a sweep file gives them:
//! `[controller@]base[+gain=value]...` with `base` one of `default`, `paper`, `tuned`,
//! `equal-activity/<1.5|3|6>`, a gain file, and on the leg `leg` (the shipped leg gains)
//! or `scenario` (the scenario's APRC-NDO gains).
use crate::experiments::paper::{aprc_ndo_tuned, equal_activity_file};
use pma_control::{AprcGains, ControllerConfig, ControllerKind};
use std::path::Path;

/// The gains `spec` gives `kind`: `Ok(None)` when it does not apply to `kind` (another
/// controller's file, `paper` for a baseline, a `controller@` prefix naming another).
/// `leg` is the scenario of a leg grid (`None` on the bench).
pub(crate) fn gains_for(
    kind: ControllerKind,
    spec: &str,
    dir: &Path,
    leg: Option<&pma_leg::LoadedScenario>,
) -> Result<Option<ControllerConfig>, String> {
    let (only, rest) = match spec.split_once('@') {
        Some((c, r)) => (Some(c), r),
        None => (None, spec),
    };
    if let Some(c) = only {
        c.parse::<ControllerKind>()
            .map_err(|e| format!("`{spec}`: {e}"))?;
        if c != kind.as_str() {
            return Ok(None);
        }
    }
    let mut parts = rest.split('+');
    let base = parts.next().unwrap_or_default();
    let Some(mut config) =
        base_gains(kind, base, dir, leg).map_err(|m| format!("`{spec}`: {m}"))?
    else {
        return Ok(None);
    };
    for change in parts {
        let (field, value) = change
            .split_once('=')
            .ok_or_else(|| format!("`{spec}`: `{change}` is not gain=value"))?;
        let v: f64 = value
            .parse()
            .map_err(|_| format!("`{spec}`: `{value}` is not a number"))?;
        config
            .set_gain(field, v)
            .map_err(|e| format!("`{spec}`: {e}"))?;
    }
    config
        .validate()
        .map_err(|e| format!("`{spec}` for {kind}: {e}"))?;
    Ok(Some(config))
}

fn is_aprc(kind: ControllerKind) -> bool {
    matches!(kind, ControllerKind::AprcNdo | ControllerKind::Aprc)
}

/// APRC and APRC-NDO share one gain set: a file of either drives both.
fn as_kind(config: ControllerConfig, kind: ControllerKind) -> Option<ControllerConfig> {
    match (config, kind) {
        (ControllerConfig::AprcNdo(g) | ControllerConfig::Aprc(g), ControllerKind::AprcNdo) => {
            Some(ControllerConfig::AprcNdo(g))
        }
        (ControllerConfig::AprcNdo(g) | ControllerConfig::Aprc(g), ControllerKind::Aprc) => {
            Some(ControllerConfig::Aprc(g))
        }
        (c, k) if c.kind() == k => Some(c),
        _ => None,
    }
}

fn parse(text: &str) -> Result<ControllerConfig, String> {
    ControllerConfig::from_toml_str(text).map_err(|e| e.to_string())
}

fn base_gains(
    kind: ControllerKind,
    base: &str,
    dir: &Path,
    leg: Option<&pma_leg::LoadedScenario>,
) -> Result<Option<ControllerConfig>, String> {
    Ok(match (base, leg) {
        ("leg" | "scenario", None) => {
            return Err(format!(
                "`{base}` gains are the leg's: use them in a [[leg]] grid"
            ))
        }
        // APRC runs APRC-NDO's leg gains with the observer off, as on the bench.
        ("leg", Some(_)) if is_aprc(kind) => as_kind(leg_gains(ControllerKind::AprcNdo)?, kind),
        ("leg", Some(_)) => Some(leg_gains(kind)?),
        ("scenario", Some(loaded)) if is_aprc(kind) => {
            Some(pma_leg::scenario::base_config(loaded, kind))
        }
        ("scenario", Some(_)) => None,
        _ => base_gains_by_name(kind, base, dir)?,
    })
}

fn leg_gains(kind: ControllerKind) -> Result<ControllerConfig, String> {
    pma_leg::control::leg_gains(kind).map_err(|e| e.to_string())
}

fn base_gains_by_name(
    kind: ControllerKind,
    base: &str,
    dir: &Path,
) -> Result<Option<ControllerConfig>, String> {
    Ok(match base {
        "default" => Some(kind.default_config()),
        "paper" if is_aprc(kind) => as_kind(ControllerConfig::AprcNdo(AprcGains::PAPER), kind),
        "paper" => None,
        "tuned" if is_aprc(kind) => as_kind(parse(aprc_ndo_tuned())?, kind),
        "tuned" => Some(kind.default_config()),
        b if b.starts_with("equal-activity/") => {
            let budget = &b["equal-activity/".len()..];
            if !["1.5", "3", "6"].contains(&budget) {
                return Err(format!("no equal-activity budget `{budget}` (1.5, 3 or 6 bar/s)"));
            }
            match equal_activity_file(budget, kind.as_str()) {
                Some(text) => as_kind(parse(text)?, kind),
                None => None,
            }
        }
        b if b.ends_with(".toml") => {
            let path = dir.join(b);
            let text = std::fs::read_to_string(&path)
                .map_err(|e| format!("cannot read `{}`: {e}", path.display()))?;
            as_kind(parse(&text)?, kind)
        }
        other => {
            return Err(format!(
                "unknown gain set `{other}` (default, paper, tuned, equal-activity/<1.5|3|6>, a .toml file, and on the leg: leg, scenario)"
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_sets_by_name() {
        let d = Path::new(".");
        let k = ControllerKind::AprcNdo;
        assert_eq!(
            gains_for(k, "paper", d, None).unwrap(),
            Some(ControllerConfig::AprcNdo(AprcGains::PAPER))
        );
        assert_eq!(
            gains_for(ControllerKind::Pid, "paper", d, None).unwrap(),
            None
        );
        assert_eq!(
            gains_for(ControllerKind::Pid, "aprc-ndo@default", d, None).unwrap(),
            None
        );
        match gains_for(k, "aprc-ndo@paper+proxy_mass=5", d, None).unwrap() {
            Some(ControllerConfig::AprcNdo(g)) => assert_eq!(g.proxy_mass, 5.0),
            other => panic!("{other:?}"),
        }
        assert!(gains_for(ControllerKind::Aprc, "equal-activity/3", d, None)
            .unwrap()
            .is_some());
        assert!(gains_for(k, "equal-activity/4", d, None)
            .unwrap_err()
            .contains("budget"));
        assert!(gains_for(k, "paper+mass=3", d, None)
            .unwrap_err()
            .contains("mass"));
        assert!(gains_for(k, "paper+proxy_mass=0", d, None)
            .unwrap_err()
            .contains("m_p"));
        assert!(gains_for(k, "lqr@paper", d, None)
            .unwrap_err()
            .contains("lqr"));
        assert!(gains_for(k, "fancy", d, None)
            .unwrap_err()
            .contains("fancy"));
        assert!(gains_for(k, "leg", d, None)
            .unwrap_err()
            .contains("[[leg]]"));
    }

    #[test]
    fn leg_gain_sets_are_the_shipped_leg_gains_and_the_scenarios() {
        let d = Path::new(".");
        let loaded = pma_leg::Scenario::load("gait_training").unwrap();
        let leg = Some(&loaded);
        for kind in ControllerKind::ALL {
            let shipped = pma_leg::control::leg_gains(kind).unwrap();
            let got = gains_for(kind, "leg", d, leg).unwrap().unwrap();
            match kind {
                ControllerKind::Aprc => assert_eq!(
                    got,
                    as_kind(
                        pma_leg::control::leg_gains(ControllerKind::AprcNdo).unwrap(),
                        kind
                    )
                    .unwrap()
                ),
                _ => assert_eq!(got, shipped),
            }
        }
        assert_eq!(
            gains_for(ControllerKind::AprcNdo, "scenario", d, leg).unwrap(),
            Some(ControllerConfig::AprcNdo(loaded.scenario.aprc_gains()))
        );
        assert_eq!(
            gains_for(ControllerKind::Pid, "scenario", d, leg).unwrap(),
            None
        );
    }
}
