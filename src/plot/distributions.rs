use super::DrawResult;
use super::*;
use plotters::prelude::*;
use std::path::Path;

/// One empirical distribution of an [`ecdf_panels`] figure: its panel, its legend label
/// and its values.
struct Distribution {
    panel: String,
    /// The colour's: the controller and its gains.
    label: String,
    /// The line's dashes: a second factor (the patient group), `""` when there is none.
    variant: String,
    values: Vec<f64>,
}

/// Adds `value` to the distribution of `(panel, label, variant)`, created in order of
/// appearance.
fn push_value(
    groups: &mut Vec<Distribution>,
    panel: &str,
    (label, variant): (String, &str),
    value: f64,
) {
    match groups
        .iter_mut()
        .find(|g| g.panel == panel && g.label == label && g.variant == variant)
    {
        Some(g) => g.values.push(value),
        None => groups.push(Distribution {
            panel: panel.to_owned(),
            label,
            variant: variant.to_owned(),
            values: vec![value],
        }),
    }
}

/// A sweep's RTE distributions: one panel per reference, the empirical CDF of RTE (log
/// scale) of each controller and gain set, so that median, tail and worst read at once.
pub fn rte_distributions(path: &Path, name: &str, runs: &pma_studies::sweep::Runs) -> DrawResult {
    let mut groups = Vec::new();
    for r in runs.values().filter_map(pma_studies::sweep::Record::bench) {
        let label = format!("{} ({})", r.controller, r.gains);
        push_value(&mut groups, &r.reference, (label, ""), r.rte_percent);
    }
    ecdf_panels(
        path,
        (
            &format!("Sweep `{name}`: RTE of every run"),
            "empirical cumulative distribution per controller (gains); RTE = mean |x_d - x| / 30 mm",
        ),
        "RTE (%)",
        &groups,
    )
}

/// A sweep's leg runs: one panel per joint (and scenario), the empirical CDF of the RMS
/// tracking error (log scale) of each controller and gain set (and patient group).
pub fn leg_rms_distributions(
    path: &Path,
    name: &str,
    runs: &pma_studies::sweep::Runs,
) -> DrawResult {
    let leg: Vec<_> = runs
        .values()
        .filter_map(pma_studies::sweep::Record::leg)
        .collect();
    let several = |f: fn(&pma_studies::sweep::LegRunRecord) -> &str| {
        leg.iter()
            .any(|r| f(r) != leg.first().map_or("", |r0| f(r0)))
    };
    let (scenarios, patient_groups) = (several(|r| &r.scenario), several(|r| &r.patient_group));
    let mut groups = Vec::new();
    // One colour per controller whatever the patient (regression, issue 26: each
    // controller and patient group had its own colour); the group is the line's dashes.
    for r in &leg {
        let label = format!("{} ({})", r.controller, r.gains);
        let variant = if patient_groups {
            r.patient_group.as_str()
        } else {
            ""
        };
        for (joint, rms) in [("hip", r.hip_rms_deg), ("knee", r.knee_rms_deg)] {
            let panel = if scenarios {
                format!("{}: {joint}", r.scenario)
            } else {
                joint.to_owned()
            };
            push_value(&mut groups, &panel, (label.clone(), variant), rms);
        }
    }
    ecdf_panels(
        path,
        (
            &format!("Sweep `{name}`: the leg's tracking error, every run"),
            "empirical cumulative distribution per controller (gains); RMS error after the first stride",
        ),
        "RMS error (deg)",
        &groups,
    )
}

/// Empirical CDFs on a log axis, one panel per distinct `panel`, a colour per `label`.
fn ecdf_panels(
    path: &Path,
    (title, setting): (&str, &str),
    x_desc: &str,
    groups: &[Distribution],
) -> DrawResult {
    let unique = |v: Vec<String>| {
        v.into_iter().fold(Vec::new(), |mut out: Vec<String>, x| {
            if !out.contains(&x) {
                out.push(x);
            }
            out
        })
    };
    let references = unique(groups.iter().map(|g| g.panel.clone()).collect());
    let labels = unique(groups.iter().map(|g| g.label.clone()).collect());
    let variants = unique(groups.iter().map(|g| g.variant.clone()).collect());
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (panels, legend) = body.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let cells = panels.split_evenly((references.len().max(1), 1));
    let finite = groups
        .iter()
        .flat_map(|g| g.values.iter())
        .filter(|v| v.is_finite() && **v > 0.0);
    let (lo, hi) = finite.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    let (lo, hi) = if lo <= hi {
        (
            10f64.powf(lo.log10().floor()),
            10f64.powf(hi.log10().ceil()),
        )
    } else {
        (1e-3, 1e3)
    };
    for (cell, reference) in cells.iter().zip(&references) {
        let mut chart = ChartBuilder::on(cell)
            .caption(reference.as_str(), (FONT, LEGEND_PX))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((lo..hi).log_scale(), 0.0..1.0)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("share of runs")
            .axis_desc_style((FONT, AXIS_DESC_PX))
            .label_style((FONT, TICK_PX))
            .x_label_formatter(&|v| format!("{v}"))
            .draw()?;
        for g in groups.iter().filter(|g| &g.panel == reference) {
            let i = labels.iter().position(|l| *l == g.label).unwrap_or(0);
            let dash = variants.iter().position(|v| *v == g.variant).unwrap_or(0);
            let mut v: Vec<f64> = g
                .values
                .iter()
                .map(|x| if x.is_finite() { x.clamp(lo, hi) } else { hi })
                .collect();
            v.sort_by(f64::total_cmp);
            let n = v.len() as f64;
            let steps = v
                .iter()
                .enumerate()
                .flat_map(|(k, x)| [(*x, k as f64 / n), (*x, (k + 1) as f64 / n)]);
            let style = colour(i).stroke_width(LINE_PX);
            match DASHES[dash % DASHES.len()] {
                None => chart.draw_series(LineSeries::new(steps, style))?,
                Some((on, off)) => {
                    chart.draw_series(DashedLineSeries::new(steps, on, off, style))?
                }
            };
        }
    }
    let mut entries: Vec<LegendEntry> = labels
        .iter()
        .enumerate()
        .map(|(i, l)| LegendEntry {
            label: l.clone(),
            style: colour(i).stroke_width(3),
        })
        .collect();
    let mut title = "controller (gains)".to_owned();
    if variants.len() > 1 {
        title.push_str(" in colour;\npatient group in dashes");
        entries.extend(variants.iter().enumerate().map(|(k, v)| LegendEntry {
            label: format!("{v}: {}", DASH_NAMES[k % DASHES.len()]),
            style: BLACK.stroke_width(1),
        }));
    }
    legend_column(&legend, &title, &entries)?;
    root.present()?;
    Ok(())
}
