//! A sweep's summary: its runs grouped by controller, gains, plant group, reference and
//! event, with the distribution of their figures.
use super::RunRecord;
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
    /// One per group.
    pub groups: Vec<GroupSummary>,
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
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
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
pub fn summarise(name: &str, runs: &BTreeMap<usize, RunRecord>, missing: usize) -> Summary {
    let mut groups: BTreeMap<Key, Vec<&RunRecord>> = BTreeMap::new();
    for r in runs.values() {
        groups.entry(key(r)).or_default().push(r);
    }
    // Groups in the order of their first run, so tables follow the sweep file.
    let mut ordered: Vec<(usize, GroupSummary)> = groups
        .into_iter()
        .map(|((reference, event, plant_group, controller, gains), rs)| {
            let rte: Vec<f64> = rs.iter().map(|r| r.rte_percent).collect();
            let first = rs.iter().map(|r| r.run).min().unwrap_or(0);
            (
                first,
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
                    share_rte_above_5: share(&rs, |r| {
                        r.rte_percent > 5.0 || r.rte_percent.is_nan()
                    }),
                    share_at_limit_above_10: share(&rs, |r| r.limit_fraction > 0.1),
                    variation_median_bar_per_s: quantile(
                        &rs.iter()
                            .map(|r| r.command_variation_bar_per_s)
                            .collect::<Vec<_>>(),
                        0.5,
                    ),
                    all_finite: rs.iter().all(|r| r.finite),
                    events: events(&rs),
                },
            )
        })
        .collect();
    ordered.sort_by_key(|(first, _)| *first);
    Summary {
        name: name.to_owned(),
        runs: runs.len(),
        missing,
        groups: ordered.into_iter().map(|(_, g)| g).collect(),
    }
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
    md
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
