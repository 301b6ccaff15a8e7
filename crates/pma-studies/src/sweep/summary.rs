//! A sweep's summary: its bench runs grouped by controller, gains, plant group, reference
//! and event, its leg runs by scenario, patient group, controller and gains, with the
//! distribution of their figures.
use super::{FailedRecord, LegRunRecord, Record, RunRecord, Runs};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The summary of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Sweep name.
    pub name: String,
    /// Runs summarised.
    pub runs: usize,
    /// Runs of the sweep not (yet) in the directories.
    pub missing: usize,
    /// Runs that failed (counted in `runs`, in no group).
    pub failed: usize,
    /// Each failed run: its index, what it ran, its scenario and why.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub failed_runs: Vec<FailedRecord>,
    /// One per group of bench runs.
    pub groups: Vec<GroupSummary>,
    /// One per group of leg runs.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub leg_groups: Vec<LegGroupSummary>,
}

/// One group of leg runs (they differ only in the patient within a group, or the seed).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LegGroupSummary {
    /// Scenario.
    pub scenario: String,
    /// Patient group (`population` for sampled patients).
    pub patient_group: String,
    /// Controller.
    pub controller: String,
    /// Gain set.
    pub gains: String,
    /// Runs.
    pub runs: usize,
    /// Hip RMS tracking error (deg): median.
    pub hip_rms_median_deg: f64,
    /// Knee RMS tracking error (deg): median.
    pub knee_rms_median_deg: f64,
    /// The worse joint's RMS error (deg): 95th percentile.
    pub rms_p95_deg: f64,
    /// Worst.
    pub rms_worst_deg: f64,
    /// Largest tracking error of any joint (deg): worst.
    pub max_error_worst_deg: f64,
    /// Spasms over the runs.
    pub spasms: usize,
    /// Largest peak deviation during a spasm (deg; `null` without spasms).
    pub spasm_deviation_worst_deg: Option<f64>,
    /// Spasms not recovered from within 3 s.
    pub spasms_unrecovered: usize,
    /// Largest muscle force over its rating: worst.
    pub force_over_rated_worst: f64,
    /// Time beyond the URDF joint limits (s): worst.
    pub time_outside_limits_worst_s: f64,
    /// Median command variation (bar/s).
    pub variation_median_bar_per_s: f64,
    /// Runs the supervisor stopped.
    pub faults: usize,
    /// Whether every run stayed finite.
    pub all_finite: bool,
}

/// One group of runs (they differ only in the plant within a group, or the seed).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupSummary {
    /// Controller.
    pub controller: String,
    /// Gain set.
    pub gains: String,
    /// Plant group.
    pub plant_group: String,
    /// Reference.
    pub reference: String,
    /// Event.
    pub event: String,
    /// Runs.
    pub runs: usize,
    /// RTE (%): median.
    pub rte_median: f64,
    /// 95th percentile.
    pub rte_p95: f64,
    /// Worst.
    pub rte_worst: f64,
    /// Share of runs above 5 % RTE.
    pub share_rte_above_5: f64,
    /// Share of runs with the command at a valve limit over 10 % of the time.
    pub share_at_limit_above_10: f64,
    /// Median command variation (bar/s).
    pub variation_median_bar_per_s: f64,
    /// Whether every run stayed finite.
    pub all_finite: bool,
    /// Per event of the runs.
    pub events: Vec<EventSummary>,
}

/// One event over a group's runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventSummary {
    /// Event.
    pub name: String,
    /// Overshoot (m): median.
    pub overshoot_median_m: f64,
    /// Worst.
    pub overshoot_worst_m: f64,
    /// Largest error (m): worst.
    pub peak_error_worst_m: f64,
    /// Peak speed (m/s): worst.
    pub peak_speed_worst_m_s: f64,
    /// Peak command rate (bar/s): worst.
    pub peak_command_rate_worst_bar_per_s: f64,
    /// Time at the valve limits (s): worst.
    pub limit_time_worst_s: f64,
    /// Settling time of the runs that settled (s): worst.
    pub settling_worst_s: Option<f64>,
    /// Runs that did not settle within the window.
    pub unsettled: usize,
    /// Error integral (m s): median.
    pub error_integral_median_m_s: f64,
    /// Obstacle contact force (N): worst.
    pub peak_contact_force_worst_n: f64,
}

/// The `q`-quantile (nearest rank) of `values`; NaN when empty.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    pma_control::nearest_rank(&v, q)
}

fn max(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(f64::NAN, f64::max)
}

type Key = (String, String, String, String, String);

fn key(r: &RunRecord) -> Key {
    (
        r.reference.clone(),
        r.event.clone(),
        r.plant_group.clone(),
        r.controller.clone(),
        r.gains.clone(),
    )
}

fn share(runs: &[&RunRecord], pred: impl Fn(&RunRecord) -> bool) -> f64 {
    runs.iter().filter(|r| pred(r)).count() as f64 / runs.len().max(1) as f64
}

fn events(runs: &[&RunRecord]) -> Vec<EventSummary> {
    let names: Vec<String> = runs
        .first()
        .map(|r| r.events.iter().map(|e| e.name.clone()).collect())
        .unwrap_or_default();
    names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let e: Vec<_> = runs.iter().filter_map(|r| r.events.get(i)).collect();
            let settled: Vec<f64> = e.iter().filter_map(|m| m.settling_s).collect();
            EventSummary {
                name: name.clone(),
                overshoot_median_m: quantile(
                    &e.iter().map(|m| m.overshoot_m).collect::<Vec<_>>(),
                    0.5,
                ),
                overshoot_worst_m: max(e.iter().map(|m| m.overshoot_m)),
                peak_error_worst_m: max(e.iter().map(|m| m.peak_error_m)),
                peak_speed_worst_m_s: max(e.iter().map(|m| m.peak_speed_m_s)),
                peak_command_rate_worst_bar_per_s: max(e
                    .iter()
                    .map(|m| m.peak_command_rate_bar_per_s)),
                limit_time_worst_s: max(e.iter().map(|m| m.limit_time_s)),
                settling_worst_s: (!settled.is_empty()).then(|| max(settled.iter().copied())),
                unsettled: e.len() - settled.len(),
                error_integral_median_m_s: quantile(
                    &e.iter().map(|m| m.error_integral_m_s).collect::<Vec<_>>(),
                    0.5,
                ),
                peak_contact_force_worst_n: max(e.iter().map(|m| m.peak_contact_force_n)),
            }
        })
        .collect()
}

/// Groups and summarises `runs`.
pub fn summarise(name: &str, runs: &Runs, missing: usize) -> Summary {
    Summary {
        name: name.to_owned(),
        runs: runs.len(),
        missing,
        failed: runs.values().filter(|r| r.failed().is_some()).count(),
        failed_runs: runs.values().filter_map(Record::failed).cloned().collect(),
        groups: bench_groups(runs.values().filter_map(Record::bench)),
        leg_groups: leg_groups(runs.values().filter_map(Record::leg)),
    }
}

/// Groups in the order of their first run, so tables follow the sweep file.
fn in_file_order<K: Ord, R, G>(
    runs: impl Iterator<Item = R>,
    key: impl Fn(&R) -> K,
    first: impl Fn(&R) -> usize,
    summarise: impl Fn(K, Vec<R>) -> G,
) -> Vec<G> {
    let mut groups: BTreeMap<K, Vec<R>> = BTreeMap::new();
    for r in runs {
        groups.entry(key(&r)).or_default().push(r);
    }
    let mut ordered: Vec<(usize, G)> = groups
        .into_iter()
        .map(|(k, rs)| (rs.iter().map(&first).min().unwrap_or(0), summarise(k, rs)))
        .collect();
    ordered.sort_by_key(|(first, _)| *first);
    ordered.into_iter().map(|(_, g)| g).collect()
}

fn leg_groups<'a>(runs: impl Iterator<Item = &'a LegRunRecord>) -> Vec<LegGroupSummary> {
    let key = |r: &&LegRunRecord| {
        (
            r.scenario.clone(),
            r.patient_group.clone(),
            r.controller.clone(),
            r.gains.clone(),
        )
    };
    in_file_order(
        runs,
        key,
        |r| r.run,
        |(scenario, patient_group, controller, gains), rs| {
            let of = |f: fn(&LegRunRecord) -> f64| rs.iter().map(|r| f(r)).collect::<Vec<_>>();
            let worse = of(|r| r.hip_rms_deg.max(r.knee_rms_deg));
            let deviations: Vec<f64> = rs
                .iter()
                .filter_map(|r| r.spasm_max_deviation_deg)
                .collect();
            LegGroupSummary {
                scenario,
                patient_group,
                controller,
                gains,
                runs: rs.len(),
                hip_rms_median_deg: quantile(&of(|r| r.hip_rms_deg), 0.5),
                knee_rms_median_deg: quantile(&of(|r| r.knee_rms_deg), 0.5),
                rms_p95_deg: quantile(&worse, 0.95),
                rms_worst_deg: max(worse.iter().copied()),
                max_error_worst_deg: max(rs.iter().map(|r| r.hip_max_deg.max(r.knee_max_deg))),
                spasms: rs.iter().map(|r| r.spasms).sum(),
                spasm_deviation_worst_deg: (!deviations.is_empty())
                    .then(|| max(deviations.iter().copied())),
                spasms_unrecovered: rs.iter().map(|r| r.spasms_unrecovered).sum(),
                force_over_rated_worst: max(rs.iter().map(|r| r.peak_force_over_rated)),
                time_outside_limits_worst_s: max(rs.iter().map(|r| r.time_outside_limits_s)),
                variation_median_bar_per_s: quantile(&of(|r| r.command_variation_bar_per_s), 0.5),
                faults: rs.iter().filter(|r| r.fault.is_some()).count(),
                all_finite: rs.iter().all(|r| r.finite),
            }
        },
    )
}

fn bench_groups<'a>(runs: impl Iterator<Item = &'a RunRecord>) -> Vec<GroupSummary> {
    in_file_order(
        runs,
        |r| key(r),
        |r| r.run,
        |(reference, event, plant_group, controller, gains), rs| {
            let rte: Vec<f64> = rs.iter().map(|r| r.rte_percent).collect();
            GroupSummary {
                controller,
                gains,
                plant_group,
                reference,
                event,
                runs: rs.len(),
                rte_median: quantile(&rte, 0.5),
                rte_p95: quantile(&rte, 0.95),
                rte_worst: max(rte.iter().copied()),
                // A NaN RTE (a run that blew up) counts as above.
                share_rte_above_5: share(&rs, |r| r.rte_percent > 5.0 || r.rte_percent.is_nan()),
                share_at_limit_above_10: share(&rs, |r| r.limit_fraction > 0.1),
                variation_median_bar_per_s: quantile(
                    &rs.iter()
                        .map(|r| r.command_variation_bar_per_s)
                        .collect::<Vec<_>>(),
                    0.5,
                ),
                all_finite: rs.iter().all(|r| r.finite),
                events: events(&rs),
            }
        },
    )
}

fn opt(v: Option<f64>, scale: f64) -> String {
    v.map_or("-".into(), |x| format!("{:.3}", x * scale))
}

/// The summary as Markdown: one table per reference, event and plant group.
pub fn markdown(s: &Summary) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Sweep `{}`: {} runs", s.name, s.runs);
    if s.missing > 0 {
        let _ = writeln!(
            md,
            "\n**{} runs missing** (shards not merged yet?)",
            s.missing
        );
    }
    if s.failed > 0 {
        let _ = writeln!(
            md,
            "\n**Runs that failed: {}** (in no table; a resume does not run them again):\n",
            s.failed
        );
        for f in &s.failed_runs {
            let _ = writeln!(md, "- run {}, {}: {}", f.run, f.ran, f.failed);
        }
    }
    // One table per reference, event and plant group, in the order they first appear.
    let table_of = |g: &GroupSummary| (g.reference.clone(), g.event.clone(), g.plant_group.clone());
    let mut tables: Vec<(String, String, String)> = Vec::new();
    for g in &s.groups {
        if !tables.contains(&table_of(g)) {
            tables.push(table_of(g));
        }
    }
    let mut groups: Vec<&GroupSummary> = s.groups.iter().collect();
    groups.sort_by_key(|g| tables.iter().position(|t| *t == table_of(g)));
    let mut last: Option<(String, String, String)> = None;
    for g in groups {
        let here = (g.reference.clone(), g.event.clone(), g.plant_group.clone());
        if last.as_ref() != Some(&here) {
            let _ = writeln!(
                md,
                "\n## {} reference, event `{}`, plant {}\n\n| controller | gains | runs | RTE median | p95 | worst | > 5 % | at limit > 10 % | bar/s |\n|---|---|---|---|---|---|---|---|---|",
                g.reference, g.event, g.plant_group
            );
            last = Some(here);
        }
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} % | {:.3} % | {:.3} % | {:.1} % | {:.1} % | {:.1} |",
            g.controller,
            g.gains,
            g.runs,
            g.rte_median,
            g.rte_p95,
            g.rte_worst,
            100.0 * g.share_rte_above_5,
            100.0 * g.share_at_limit_above_10,
            g.variation_median_bar_per_s
        );
    }
    event_tables(&mut md, s);
    leg_tables(&mut md, s);
    md
}

fn leg_tables(md: &mut String, s: &Summary) {
    let mut last: Option<(&str, &str)> = None;
    for g in &s.leg_groups {
        let here = (g.scenario.as_str(), g.patient_group.as_str());
        if last != Some(here) {
            let _ = writeln!(
                md,
                "\n## Leg: scenario `{}`, patients {}\n\nTracking error after the first stride (RMS, deg; the worse joint's p95 and worst); spasms' largest deviation from the reference; the largest muscle force over its rating; time beyond the URDF limits; runs the supervisor stopped.\n\n| controller | gains | runs | hip RMS median | knee RMS median | worse p95 | worst | max error | spasms | spasm deviation | not recovered | force / rated | outside limits (s) | bar/s | faults |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
                g.scenario, g.patient_group
            );
            last = Some(here);
        }
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {} | {} | {:.2} | {:.3} | {:.1} | {}{} |",
            g.controller,
            g.gains,
            g.runs,
            g.hip_rms_median_deg,
            g.knee_rms_median_deg,
            g.rms_p95_deg,
            g.rms_worst_deg,
            g.max_error_worst_deg,
            g.spasms,
            g.spasm_deviation_worst_deg.map_or("-".into(), |d| format!("{d:.2}")),
            g.spasms_unrecovered,
            g.force_over_rated_worst,
            g.time_outside_limits_worst_s,
            g.variation_median_bar_per_s,
            g.faults,
            if g.all_finite { "" } else { " (non-finite)" }
        );
    }
}

fn event_tables(md: &mut String, s: &Summary) {
    let with_events: Vec<&GroupSummary> =
        s.groups.iter().filter(|g| !g.events.is_empty()).collect();
    if with_events.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Events\n\nPer event (worst over the group's runs unless said): largest error, overshoot past the reference after it, peak load speed, peak command rate, time at the valve limits, settling to 0.5 mm (`-`: not within 3 s), error integral (median), obstacle contact force.\n\n| plant | controller | gains | event | peak error (mm) | overshoot (mm) | speed (mm/s) | rate (bar/s) | at limits (s) | settling (s) | not settled | integral (mm s) | contact (N) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for g in with_events {
        for e in &g.events {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.2} | {:.2} | {:.1} | {:.0} | {:.3} | {} | {} | {:.3} | {:.0} |",
                g.plant_group,
                g.controller,
                g.gains,
                e.name,
                e.peak_error_worst_m * 1e3,
                e.overshoot_worst_m * 1e3,
                e.peak_speed_worst_m_s * 1e3,
                e.peak_command_rate_worst_bar_per_s,
                e.limit_time_worst_s,
                opt(e.settling_worst_s, 1.0),
                e.unsettled,
                e.error_integral_median_m_s * 1e3,
                e.peak_contact_force_worst_n
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_quantiles() {
        let v: Vec<f64> = (1..=20).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 10.0);
        assert_eq!(quantile(&v, 0.95), 19.0);
        assert_eq!(quantile(&v, 1.0), 20.0);
        assert!(quantile(&[], 0.5).is_nan());
    }
}
