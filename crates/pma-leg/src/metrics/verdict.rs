//! Whether a treadmill run walked, and if not why: the verdict a physiotherapist gives a
//! session on a gait trainer, from the run's own figures. A run that does not walk says so
//! (`walking: false` with its reasons, a non-zero exit of `simulate`), however finite its
//! numbers are.
use crate::base::LegFault;
use crate::metrics::LegReport;

/// What walking means here, per leg (every bound is the gait trainer's, stated once).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct WalkingCriteria {
    /// Largest stance-phase RMS tracking error of hip or knee (deg): 2 deg, the figure
    /// issue 46 fixes for a trainer that walks its patient (the nominal trainer tracks to
    /// 0.02-0.06 deg; a buckled knee is off by 55-60).
    pub stance_rms_max_deg: f64,
    /// Largest relative difference between the belt's mean load and what it must carry
    /// (`(1 - support) x system weight`): 15 %.
    pub belt_load_tolerance: f64,
    /// Strides a foot may miss against the run's length: 2 (the first and the last,
    /// which a run's edges cut).
    pub strides_missed_max: usize,
    /// Largest peak force of any muscle over its rating.
    pub force_over_rating_max: f64,
}

impl Default for WalkingCriteria {
    fn default() -> Self {
        Self {
            stance_rms_max_deg: 2.0,
            belt_load_tolerance: 0.15,
            strides_missed_max: 2,
            force_over_rating_max: 1.0,
        }
    }
}

/// A collapse the trainer's safety stopped.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CollapseReport {
    /// When (s).
    pub t_s: f64,
    /// What gave way, on one line.
    pub what: String,
}

/// The verdict on a treadmill run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WalkingVerdict {
    /// Whether the patient walked within every criterion.
    pub walking: bool,
    /// Each criterion missed, one line each (empty when walking).
    pub reasons: Vec<String>,
    /// The strides each foot had to take: the run's length in strides, less
    /// `strides_missed_max`.
    pub strides_expected: usize,
    /// The collapse that stopped the run, if one did.
    pub collapse: Option<CollapseReport>,
    /// The criteria applied.
    pub criteria: WalkingCriteria,
}

impl WalkingVerdict {
    /// The verdict's one line: what failed first and when.
    pub fn line(&self) -> String {
        match (self.walking, self.reasons.as_slice()) {
            (true, _) | (false, []) => "the patient walked".into(),
            (false, [only]) => format!("the patient did not walk: {only}"),
            (false, [first, rest @ ..]) => format!(
                "the patient did not walk: {first} (and {} more: --json's walking.reasons)",
                rest.len()
            ),
        }
    }
}

/// The verdict on `report`, a treadmill run of `planned_s` at a stride of `stride_s`
/// that ended with `fault` (if any); `None` off the treadmill.
pub fn judge(
    report: &LegReport,
    planned_s: f64,
    stride_s: f64,
    fault: Option<&LegFault>,
    criteria: WalkingCriteria,
) -> Option<WalkingVerdict> {
    let t = report.treadmill.as_ref()?;
    let mut reasons = Vec::new();
    let collapse = fault
        .filter(|f| f.name == "collapse")
        .map(|f| CollapseReport {
            t_s: f.t_s,
            what: f.message.clone(),
        });
    if let Some(c) = &collapse {
        reasons.push(format!(
            "collapse at {:.2} s: {}; the trainer stopped the belt, the harness took the weight and the muscles vented",
            c.t_s, c.what
        ));
    }
    let strides_expected =
        ((planned_s / stride_s).floor() as usize).saturating_sub(criteria.strides_missed_max);
    for (side, foot) in &t.feet {
        if foot.strides < strides_expected {
            reasons.push(format!(
                "the {side} foot took {} strides of the {strides_expected} expected",
                foot.strides
            ));
        }
        for (joint, p) in &foot.tracking {
            let rms = p.stance_rms_deg;
            // NaN (no stance to measure) misses the criterion too.
            if rms.is_nan() || rms > criteria.stance_rms_max_deg {
                reasons.push(format!(
                    "the {side} {joint}'s stance-phase RMS error is {} deg (at most {})",
                    figure(rms, 2),
                    criteria.stance_rms_max_deg
                ));
            }
        }
    }
    let load = t.mean_belt_load_bw / t.expected_belt_load_bw;
    if !((1.0 - criteria.belt_load_tolerance..=1.0 + criteria.belt_load_tolerance).contains(&load))
    {
        reasons.push(format!(
            "the belt carried {} BW of the {:.3} expected ({} of it, within {:.0} %)",
            figure(t.mean_belt_load_bw, 3),
            t.expected_belt_load_bw,
            figure(load, 2),
            100.0 * criteria.belt_load_tolerance
        ));
    }
    let over = report.safety.over_rating(criteria.force_over_rating_max);
    if !over.is_empty() {
        reasons.push(format!(
            "{} muscle(s) over their rating: {}",
            over.len(),
            over.join(", ")
        ));
    }
    if !report.finite {
        reasons.push("the simulation went non-finite".into());
    }
    Some(WalkingVerdict {
        walking: reasons.is_empty(),
        reasons,
        strides_expected,
        collapse,
        criteria,
    })
}

/// `value` with `decimals`, or `-` where it does not exist (NaN, infinite): what every
/// text output prints for a figure a run could not give.
pub fn figure(value: f64, decimals: usize) -> String {
    if value.is_finite() {
        format!("{value:.decimals$}")
    } else {
        "-".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_figure_prints_as_a_dash() {
        assert_eq!(figure(f64::NAN, 2), "-");
        assert_eq!(figure(f64::INFINITY, 1), "-");
        assert_eq!(figure(1.23456, 2), "1.23");
    }
}
