//! The PNG plots of `paper` (plotters, bitmap backend, the embedded DejaVu Sans).
//!
//! Every figure is 1200 x 800: two title lines (the experiment; reference, plant and
//! duration), the trajectories over their reference(s), then the tracking errors. Runs of
//! one controller with one setting varied share a signed error panel; runs of different
//! controllers, whose errors span decades, get one log-scale panel each so that no run's
//! error sets the scale of the others. Legends sit in a column of their own, off the data.
use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use pma_studies::experiments::paper::{Plot, Varied};
use pma_studies::experiments::Series;
use std::ops::Range;
use std::path::Path;

/// Registers the embedded DejaVu Sans as plotters' `sans-serif`.
pub fn register_font() -> Result<()> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        include_bytes!("../assets/fonts/DejaVuSans.ttf"),
    )
    .map_err(|_| anyhow::anyhow!("the embedded DejaVuSans.ttf is not a valid font"))
}

/// A drawing step's result.
pub type DrawOutcome<T> = std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// A drawing's result.
pub type DrawResult = DrawOutcome<()>;

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type LinearChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

const SIZE: (u32, u32) = (1200, 800);
const FONT: &str = "sans-serif";
const TITLE_PX: u32 = 26;
const SETTING_PX: u32 = 18;
const AXIS_DESC_PX: u32 = 17;
const TICK_PX: u32 = 15;
const SMALL_TICK_PX: u32 = 13;
const LEGEND_PX: u32 = 16;
const TITLE_HEIGHT: u32 = 72;
const LEGEND_WIDTH: u32 = 240;
const LINE_PX: u32 = 2;
const REFERENCE_PX: u32 = 7;

/// The reference: a light grey band under the runs, so that a run that tracks it well
/// shows as a coloured line inside it and a run that does not leaves it. Opaque, so the
/// identical references of several runs do not darken where they overlap.
const REFERENCE_GREY: RGBColor = RGBColor(200, 200, 200);

/// Run colours: Tableau 10 (classic) without its olive, which reads as yellow on white,
/// and with its grey after them, since the reference band is grey (only a ninth run gets
/// it); then dark hues for the groups of a sweep (a leg sweep's controllers times patient
/// groups reach ten).
const PALETTE: [RGBColor; 14] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
    RGBColor(0, 0, 0),
    RGBColor(0, 0, 128),
    RGBColor(128, 0, 0),
    RGBColor(0, 110, 110),
    RGBColor(110, 110, 0),
];

/// Colour of run `i`.
fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// The log error panels' range (m). The tuned controllers track to a fraction of a
/// micrometre in simulation, so the floor sits two decades under 1 um; smaller errors
/// (zero crossings) are drawn at the floor.
const ERROR_FLOOR_M: f64 = 1e-8;
const ERROR_CEILING_M: f64 = 0.1;

/// Draws `plot` to `path`.
pub fn draw(path: &Path, plot: &Plot) -> DrawResult {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, &plot.title, &plot.setting)?;
    match plot.varied {
        Varied::Controller => controller_figure(&body, plot)?,
        Varied::Setting => setting_figure(&body, plot, &TRACKING_LABELS)?,
        Varied::Model => setting_figure(&body, plot, &MODEL_LABELS)?,
    }
    root.present()?;
    Ok(())
}

/// The experiment on the first line, its conditions on the second, centred.
fn title_block(area: &Area, title: &str, setting: &str) -> DrawResult {
    let centre = area.dim_in_pixel().0 as i32 / 2;
    let top = Pos::new(HPos::Center, VPos::Top);
    area.draw_text(
        title,
        &(FONT, TITLE_PX).into_font().into_text_style(area).pos(top),
        (centre, 8),
    )?;
    let style = (FONT, SETTING_PX)
        .into_font()
        .color(&BLACK.mix(0.75))
        .pos(top);
    area.draw_text(setting, &style, (centre, 44))?;
    Ok(())
}

/// What a figure's grey line and its error are.
struct Labels {
    /// The grey line in the legend (one series, or each series its own).
    grey: (&'static str, &'static str),
    /// The error panel's axis: grey minus coloured.
    error: &'static str,
}

/// A run tracking its reference.
const TRACKING_LABELS: Labels = Labels {
    grey: ("reference x_d", "each run's x_d"),
    error: "error x_d - x (mm)",
};

/// A model against the measurement (regression, issue 26: identification.png called the
/// measured position "reference x_d" and the model's error "x_d - x").
const MODEL_LABELS: Labels = Labels {
    grey: ("measured x", "each log's measured x"),
    error: "model error x - x_model (mm)",
};

/// One controller, one setting varied (or models against a measurement): trajectories
/// over signed errors, legend on the right.
fn setting_figure(area: &Area, plot: &Plot, labels: &Labels) -> DrawResult {
    let (plots, legend) = area.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let (top, bottom) = plots.split_vertically(plots.dim_in_pixel().1 / 2);
    let t_max = time_span(&plot.series);
    trajectory_panel(&top, plot, t_max)?;
    signed_error_panel(&bottom, plot, t_max, labels.error)?;
    legend_column(
        &legend,
        &plot.legend_title,
        &legend_entries(&plot.series, labels.grey),
    )
}

/// Several controllers: trajectories and legend on top, one log error panel per run below.
fn controller_figure(area: &Area, plot: &Plot) -> DrawResult {
    let (top, bottom) = area.split_vertically(300);
    let (trajectories, legend) = top.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let t_max = time_span(&plot.series);
    trajectory_panel(&trajectories, plot, t_max)?;
    legend_column(
        &legend,
        &plot.legend_title,
        &legend_entries(&plot.series, TRACKING_LABELS.grey),
    )?;
    log_error_grid(&bottom, &plot.series, t_max)
}

/// End of the time axis (s): the last sample, rounded up to a whole second.
fn time_span(series: &[Series]) -> f64 {
    series
        .iter()
        .filter_map(|s| s.t_s.last().copied())
        .fold(1.0, f64::max)
        .ceil()
}

/// The smallest and largest of `values`, widened by 5 % on each side.
fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return -1.0..1.0;
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad)..(hi + pad)
}

/// A linear tick label: enough decimals for `span`, trailing zeros dropped, and `0` for
/// anything that rounds to zero (plotters' default prints `-0.0` for a tiny negative).
fn tick_label(v: f64, span: f64) -> String {
    let decimals = (2.0 - span.abs().log10().floor()).clamp(0.0, 9.0) as usize;
    let text = format!("{v:.decimals$}");
    let text = if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        &text
    };
    if text.trim_start_matches('-').chars().all(|c| c == '0') {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

/// A power of ten of metres with its unit (`10 nm`, `1 µm`, `100 mm`).
fn decade_label(m: f64) -> String {
    let exponent = m.log10().round() as i32;
    let (unit, unit_exponent) = match exponent {
        ..=-7 => ("nm", -9),
        -6..=-4 => ("µm", -6),
        -3..=-1 => ("mm", -3),
        _ => ("m", 0),
    };
    format!("{} {unit}", 10f64.powi(exponent - unit_exponent))
}

/// A linear chart on `area` with readable tick labels and axis descriptions.
fn linear_chart<'a, 'b>(
    area: &'a Area<'b>,
    x: Range<f64>,
    y: Range<f64>,
    (x_desc, y_desc): (&str, &str),
) -> DrawOutcome<LinearChart<'a, 'b>> {
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .margin_right(20)
        .x_label_area_size(44)
        .y_label_area_size(80)
        .build_cartesian_2d(x.clone(), y.clone())?;
    let (x_span, y_span) = (x.end - x.start, y.end - y.start);
    let x_fmt = move |v: &f64| tick_label(*v, x_span);
    let y_fmt = move |v: &f64| tick_label(*v, y_span);
    chart
        .configure_mesh()
        .x_labels(11)
        .y_labels(7)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, TICK_PX))
        .axis_desc_style((FONT, AXIS_DESC_PX))
        .bold_line_style(BLACK.mix(0.15))
        .light_line_style(BLACK.mix(0.04))
        .draw()?;
    Ok(chart)
}

/// `(t, scale * v)` pairs of one series.
fn points<'s>(
    t: &'s [f64],
    v: &'s [f64],
    scale: f64,
) -> impl Iterator<Item = (f64, f64)> + Clone + 's {
    t.iter().zip(v).map(move |(t, v)| (*t, v * scale))
}

/// Whether every run tracks the same reference (the legend then names one).
fn shared_reference(series: &[Series]) -> bool {
    series
        .windows(2)
        .all(|w| w[0].reference_m == w[1].reference_m)
}

/// Positions (mm) over time, each over its run's reference.
fn trajectory_panel(area: &Area, plot: &Plot, t_max: f64) -> DrawResult {
    let series = &plot.series;
    let y = padded_range(
        series
            .iter()
            .flat_map(|s| s.reference_m.iter().chain(&s.position_m))
            .map(|v| v * 1e3),
    );
    let mut chart = linear_chart(area, 0.0..t_max, y.clone(), ("t (s)", "contraction x (mm)"))?;
    for s in series {
        let style = REFERENCE_GREY.stroke_width(REFERENCE_PX);
        chart.draw_series(LineSeries::new(points(&s.t_s, &s.reference_m, 1e3), style))?;
    }
    for (i, s) in series.iter().enumerate() {
        let style = colour(i).stroke_width(LINE_PX);
        chart.draw_series(LineSeries::new(points(&s.t_s, &s.position_m, 1e3), style))?;
    }
    event_markers(&mut chart, &plot.events, y)
}

/// Signed tracking errors (mm) of every run in one panel.
fn signed_error_panel(area: &Area, plot: &Plot, t_max: f64, y_desc: &str) -> DrawResult {
    let errors_mm = |s: &Series| -> Vec<f64> {
        s.reference_m
            .iter()
            .zip(&s.position_m)
            .map(|(r, x)| (r - x) * 1e3)
            .collect()
    };
    let errors: Vec<Vec<f64>> = plot.series.iter().map(errors_mm).collect();
    let y = padded_range(errors.iter().flatten().copied());
    let mut chart = linear_chart(area, 0.0..t_max, y.clone(), ("t (s)", y_desc))?;
    for (i, (s, e)) in plot.series.iter().zip(&errors).enumerate() {
        let style = colour(i).stroke_width(LINE_PX);
        chart.draw_series(LineSeries::new(points(&s.t_s, e, 1.0), style))?;
    }
    event_markers(&mut chart, &plot.events, y)
}

/// A dashed grey vertical line and its label at each event.
fn event_markers(chart: &mut LinearChart, events: &[(f64, String)], y: Range<f64>) -> DrawResult {
    let grey = BLACK.mix(0.55);
    for (t, label) in events {
        let line = vec![(*t, y.start), (*t, y.end)];
        chart.draw_series(DashedLineSeries::new(
            line,
            6,
            4,
            grey.stroke_width(LINE_PX),
        ))?;
        let text = Text::new(
            label.clone(),
            (6, 4),
            (FONT, LEGEND_PX).into_font().color(&grey),
        );
        chart.draw_series(std::iter::once(EmptyElement::at((*t, y.end)) + text))?;
    }
    Ok(())
}

/// One log-scale |error| panel per run, sharing the decades, under a one-line caption.
fn log_error_grid(area: &Area, series: &[Series], t_max: f64) -> DrawResult {
    let (head, grid) = area.split_vertically(28);
    let floor = decade_label(ERROR_FLOOR_M);
    let caption =
        format!("Tracking error |x_d - x| of each run, log scale (below {floor} drawn at {floor})");
    let centre = head.dim_in_pixel().0 as i32 / 2;
    let style = (FONT, LEGEND_PX)
        .into_font()
        .into_text_style(&head)
        .pos(Pos::new(HPos::Center, VPos::Top));
    head.draw_text(&caption, &style, (centre, 6))?;
    let cols = if series.len() <= 6 { 3 } else { 4 };
    let rows = series.len().div_ceil(cols).max(1);
    let cells = grid.split_evenly((rows, cols));
    for (i, (s, cell)) in series.iter().zip(&cells).enumerate() {
        let place = CellPlace {
            left: i % cols == 0,
            bottom: i + cols >= series.len(),
        };
        log_error_cell(cell, s, colour(i), t_max, place)?;
    }
    Ok(())
}

/// Where a panel sits in the grid: only the outer panels carry axis descriptions.
#[derive(Clone, Copy)]
struct CellPlace {
    left: bool,
    bottom: bool,
}

/// |x_d - x| of one run on a log scale, captioned with the run's label in its colour.
fn log_error_cell(
    area: &Area,
    s: &Series,
    col: RGBColor,
    t_max: f64,
    place: CellPlace,
) -> DrawResult {
    let caption = (FONT, LEGEND_PX).into_font().color(&col);
    let mut chart = ChartBuilder::on(area)
        .margin(6)
        .margin_right(16)
        .caption(&s.label, caption)
        .x_label_area_size(if place.bottom { 42 } else { 24 })
        .y_label_area_size(if place.left { 78 } else { 60 })
        .build_cartesian_2d(0.0..t_max, (ERROR_FLOOR_M..ERROR_CEILING_M).log_scale())?;
    let x_fmt = move |v: &f64| tick_label(*v, t_max);
    let y_fmt = |v: &f64| decade_label(*v);
    chart
        .configure_mesh()
        .x_labels(6)
        .y_labels(4)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .x_desc(if place.bottom { "t (s)" } else { "" })
        .y_desc(if place.left { "|x_d - x|" } else { "" })
        .label_style((FONT, SMALL_TICK_PX))
        .axis_desc_style((FONT, SMALL_TICK_PX + 1))
        .bold_line_style(BLACK.mix(0.15))
        .light_line_style(BLACK.mix(0.04))
        .draw()?;
    let error = s
        .t_s
        .iter()
        .zip(s.reference_m.iter().zip(&s.position_m))
        .map(|(t, (r, x))| (*t, (r - x).abs().clamp(ERROR_FLOOR_M, ERROR_CEILING_M)));
    chart.draw_series(LineSeries::new(error, col.stroke_width(1)))?;
    Ok(())
}

/// One legend row: a line sample and its label.
struct LegendEntry {
    label: String,
    style: ShapeStyle,
}

/// The reference band first, then the runs.
fn legend_entries(series: &[Series], (one, each): (&str, &str)) -> Vec<LegendEntry> {
    let reference = LegendEntry {
        label: if shared_reference(series) { one } else { each }.to_owned(),
        style: REFERENCE_GREY.stroke_width(REFERENCE_PX),
    };
    let runs = series.iter().enumerate().map(|(i, s)| LegendEntry {
        label: s.label.clone(),
        style: colour(i).stroke_width(3),
    });
    std::iter::once(reference).chain(runs).collect()
}

/// The legend in its own column: the title's lines, then one row per entry.
fn legend_column(area: &Area, title: &str, entries: &[LegendEntry]) -> DrawResult {
    const ROW: i32 = 24;
    let left = Pos::new(HPos::Left, VPos::Center);
    let text = (FONT, LEGEND_PX)
        .into_font()
        .into_text_style(area)
        .pos(left);
    let mut y = 24;
    for line in title.lines() {
        area.draw_text(line, &text, (8, y))?;
        y += ROW;
    }
    y += ROW / 3;
    for e in entries {
        legend_sample(area, (12, y), e)?;
        for line in wrapped(&e.label, LEGEND_CHARS) {
            area.draw_text(&line, &text, (58, y))?;
            y += ROW;
        }
    }
    Ok(())
}

/// Characters of a legend line that fit beside its sample in [`LEGEND_WIDTH`].
const LEGEND_CHARS: usize = 19;

/// `label` in lines of at most `width` characters, broken before ` (`, `+`, `@` or a space
/// (a word longer than `width` stays whole): a legend never runs off the picture.
fn wrapped(label: &str, width: usize) -> Vec<String> {
    let mut pieces: Vec<String> = Vec::new();
    let mut current = String::new();
    for c in label.chars() {
        if matches!(c, ' ' | '+' | '@' | '(') && !current.is_empty() {
            pieces.push(std::mem::take(&mut current));
        }
        current.push(c);
    }
    pieces.push(current);
    let mut lines: Vec<String> = Vec::new();
    for piece in pieces {
        match lines.last_mut() {
            Some(last) if last.chars().count() + piece.chars().count() <= width => {
                last.push_str(&piece)
            }
            _ => lines.push(piece.trim_start().to_owned()),
        }
    }
    lines
        .into_iter()
        .map(|l| l.trim_end().to_owned())
        .filter(|l| !l.is_empty())
        .collect()
}

/// A 36 px line sample starting at `(x, y)`.
fn legend_sample(area: &Area, (x, y): (i32, i32), e: &LegendEntry) -> DrawResult {
    area.draw(&PathElement::new(vec![(x, y), (x + 36, y)], e.style))?;
    Ok(())
}

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

/// Dash patterns (on, off in pixels) of a second factor, solid first; and their names.
const DASHES: [Option<(u32, u32)>; 4] = [None, Some((10, 5)), Some((3, 4)), Some((14, 4))];
const DASH_NAMES: [&str; 4] = ["solid", "dashed", "dotted", "long dashes"];

/// A shock experiment: one small panel per run with its reference (grey band), position
/// (colour) and proxy (black, dashed) in mm on the left axis, its pressure command (bar,
/// light) on the right axis, and the events marked.
pub fn shock(
    path: &Path,
    title: &str,
    setting: &str,
    traces: &[pma_studies::sweep::Trace],
    events: &[(f64, String)],
) -> DrawResult {
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (grid, legend) = body.split_horizontally(SIZE.0 - LEGEND_WIDTH);
    let cols = 3usize.min(traces.len().max(1));
    let rows = traces.len().div_ceil(cols).max(1);
    let cells = grid.split_evenly((rows, cols));
    let t = traces.iter().flat_map(|tr| tr.t_s.iter().copied());
    let (t0, t1) = t.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    let mm = traces.iter().flat_map(|tr| {
        tr.reference_m
            .iter()
            .chain(&tr.position_m)
            .copied()
            .filter(|v| v.is_finite())
            .map(|v| v * 1e3)
    });
    let y = padded_range(mm);
    for (k, (cell, tr)) in cells.iter().zip(traces).enumerate() {
        shock_cell(
            cell,
            tr,
            colour(k),
            (t0..t1, y.clone()),
            events,
            k / cols == rows - 1,
        )?;
    }
    let entries = vec![
        LegendEntry {
            label: "reference x_d".into(),
            style: REFERENCE_GREY.stroke_width(REFERENCE_PX),
        },
        LegendEntry {
            label: "position x (run colour)".into(),
            style: colour(0).stroke_width(3),
        },
        LegendEntry {
            label: "proxy x_p (dashed)".into(),
            style: BLACK.stroke_width(1),
        },
        LegendEntry {
            label: "command (bar, right axis)".into(),
            style: COMMAND_COLOUR.stroke_width(1),
        },
    ];
    legend_column(
        &legend,
        "each panel: one run\n(controller, gains)",
        &entries,
    )?;
    root.present()?;
    Ok(())
}

/// The command's line: light, so the positions stay in front.
const COMMAND_COLOUR: RGBColor = RGBColor(150, 150, 210);

fn shock_cell(
    area: &Area,
    tr: &pma_studies::sweep::Trace,
    col: RGBColor,
    (x, y): (Range<f64>, Range<f64>),
    events: &[(f64, String)],
    bottom: bool,
) -> DrawResult {
    let caption = (FONT, SMALL_TICK_PX + 1).into_font().color(&col);
    let mut chart = ChartBuilder::on(area)
        .margin(4)
        .caption(&tr.label, caption)
        .x_label_area_size(if bottom { 40 } else { 32 })
        .y_label_area_size(44)
        .right_y_label_area_size(52)
        .build_cartesian_2d(x.clone(), y.clone())?
        .set_secondary_coord(x.clone(), 0.0..6.0);
    let (x_span, y_span) = (x.end - x.start, y.end - y.start);
    let x_fmt = move |v: &f64| tick_label(*v, x_span);
    let y_fmt = move |v: &f64| tick_label(*v, y_span);
    chart
        .configure_mesh()
        .x_labels(5)
        .y_labels(5)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .x_desc("t (s)")
        .y_desc("mm")
        .label_style((FONT, SMALL_TICK_PX))
        .axis_desc_style((FONT, SMALL_TICK_PX))
        .bold_line_style(BLACK.mix(0.12))
        .light_line_style(BLACK.mix(0.03))
        .draw()?;
    // The unit in every tick: plotters turns a right-hand axis title upside down
    // (regression, issue 26: the "bar" label came out rotated and garbled).
    chart
        .configure_secondary_axes()
        .y_labels(4)
        .y_label_formatter(&|v: &f64| format!("{v:.0} bar"))
        .label_style((FONT, SMALL_TICK_PX))
        .axis_desc_style((FONT, SMALL_TICK_PX))
        .draw()?;
    chart.draw_secondary_series(LineSeries::new(
        points(&tr.t_s, &tr.command_pa, 1e-5),
        COMMAND_COLOUR.stroke_width(1),
    ))?;
    chart.draw_series(LineSeries::new(
        points(&tr.t_s, &tr.reference_m, 1e3),
        REFERENCE_GREY.stroke_width(5),
    ))?;
    chart.draw_series(LineSeries::new(
        points(&tr.t_s, &tr.position_m, 1e3),
        col.stroke_width(2),
    ))?;
    let proxy: Vec<(f64, f64)> = points(&tr.t_s, &tr.proxy_m, 1e3)
        .filter(|p| p.1.is_finite())
        .collect();
    chart.draw_series(DashedLineSeries::new(proxy, 4, 3, BLACK.stroke_width(1)))?;
    for (t, _) in events {
        chart.draw_series(DashedLineSeries::new(
            vec![(*t, y.start), (*t, y.end)],
            3,
            3,
            BLACK.mix(0.5).stroke_width(1),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod wrap_tests {
    use super::wrapped;

    #[test]
    fn long_legend_labels_wrap_at_their_separators() {
        assert_eq!(
            wrapped("pid (equal-activity/3)", 19),
            ["pid", "(equal-activity/3)"]
        );
        assert_eq!(
            wrapped("aprc-ndo (aprc-ndo@paper+proxy_mass=0.5)", 19),
            ["aprc-ndo (aprc-ndo", "@paper", "+proxy_mass=0.5)"]
        );
        assert_eq!(wrapped("aprc-ndo (paper)", 19), ["aprc-ndo (paper)"]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_never_print_negative_zero() {
        assert_eq!(tick_label(-0.0, 1.0), "0");
        assert_eq!(tick_label(-1e-12, 1.0), "0");
        assert_eq!(tick_label(0.2, 1.8), "0.2");
        assert_eq!(tick_label(-0.25, 1.8), "-0.25");
        assert_eq!(tick_label(20.0, 20.0), "20");
    }

    /// Regression (issue 26.15): `leg.png` of a 60 s run squeezed 36 strides into each
    /// panel; a run of more than six strides is drawn by its last four, and says so.
    #[test]
    fn leg_png_of_a_long_run_draws_its_last_strides() {
        let t: Vec<f64> = (1..=6000).map(|k| f64::from(k) * 0.01).collect();
        let (first, x, caption) = time_window(&t, 1.6);
        assert!((x.start - 53.6).abs() < 1e-9 && x.end == 60.0, "{x:?}");
        assert!(t[first] >= x.start && t[first - 1] < x.start);
        let caption = caption.expect("a caption");
        assert!(
            caption.contains("the last 4 strides (53.6-60.0 s)"),
            "{caption}"
        );
        // Five strides are drawn whole, uncaptioned; so is a run that is not a gait.
        assert_eq!(time_window(&t[..800], 1.6), (0, 0.0..8.0, None));
        assert_eq!(time_window(&t, 0.0), (0, 0.0..60.0, None));
    }

    /// A run interrupted before its second stride has nothing binned: `strides.png` still
    /// draws its frame (the figures cover the run so far), not an error.
    #[test]
    fn strides_png_of_a_run_stopped_in_its_first_stride_draws_empty_panels() {
        register_font().expect("font");
        let loaded = pma_leg::Scenario::load("gait_treadmill").expect("scenario");
        let sim = pma_leg::LegSim::new(&loaded).expect("sim");
        let cycles = pma_exo::strides::GaitCycles::new(&sim, 1.773).expect("cycles");
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("strides.png");
        let figure = StrideFigure {
            cycles: &cycles,
            norm_grf: None,
            treadmill: true,
        };
        strides_run(&path, "title", "setting", &figure).expect("drawn");
        assert!(std::fs::metadata(&path).expect("strides.png").len() > 0);
    }

    #[test]
    fn decades_carry_their_unit() {
        assert_eq!(decade_label(1e-8), "10 nm");
        assert_eq!(decade_label(1e-6), "1 µm");
        assert_eq!(decade_label(1e-4), "100 µm");
        assert_eq!(decade_label(1e-2), "10 mm");
        assert_eq!(decade_label(0.1), "100 mm");
    }
}

/// A leg run, every 10th period: what `simulate --plot` draws.
#[derive(Debug, Clone, Default)]
pub struct LegTrace {
    /// Time (s).
    pub t_s: Vec<f64>,
    /// Reference and angle (deg) of hip and knee.
    pub reference_deg: [Vec<f64>; 2],
    /// Joint angles (deg).
    pub angle_deg: [Vec<f64>; 2],
    /// Pressures (bar), muscle order of `muscles`.
    pub pressure_bar: [Vec<f64>; 4],
    /// Forces (N).
    pub force_n: [Vec<f64>; 4],
    /// The patient's torque (N m) at hip and knee.
    pub patient_nm: [Vec<f64>; 2],
    /// The device's torque on the limb (N m) at hip and knee.
    pub interaction_nm: [Vec<f64>; 2],
    /// The thigh and shank cuff forces that put it there (N, forward positive).
    pub cuff_force_n: [Vec<f64>; 2],
    /// Muscle names.
    pub muscles: Vec<String>,
    /// Spasms: joint (0 hip, 1 knee), onset and end (s).
    pub spasms: Vec<(usize, f64, f64)>,
    /// The valve's limit (bar) and the muscles' rated force (N).
    pub pressure_max_bar: f64,
    /// Rated force (N).
    pub rated_force_n: f64,
    /// On a treadmill: the ground's side of the run.
    pub ground: Option<GroundTrace>,
    /// Legs of the trainer (the joints and muscles drawn are the first's).
    pub legs: usize,
    /// The gait's stride period (s; 0: not a gait, the whole run is drawn).
    pub stride_s: f64,
    /// When the trainer's safety stopped a collapse (s), marked on every panel.
    pub collapse_s: Option<f64>,
}

/// The treadmill's side of a leg run, every 10th period as [`LegTrace`].
#[derive(Debug, Clone, Default)]
pub struct GroundTrace {
    /// Vertical ground reaction under each foot (N), leg by leg.
    pub foot_n: Vec<Vec<f64>>,
    /// The virtual other leg's force on the pelvis (N).
    pub other_leg_n: Vec<f64>,
    /// Height of the pelvis above the belt (m).
    pub pelvis_m: Vec<f64>,
    /// What the belt carries at rest, `(1 - bws) m g` (N).
    pub unsupported_n: f64,
}

/// One panel of lines over time with dashed horizontal marks and shaded spasms.
struct LinePanel<'a> {
    y_desc: &'a str,
    lines: Vec<(String, &'a [f64], RGBColor, bool)>,
    marks: Vec<(f64, String)>,
    spasms: Vec<(f64, f64)>,
    /// A moment marked by a vertical line and its label (a collapse the trainer stopped).
    event: Option<(f64, String)>,
}

/// `y` raised at the top by the height of an upper-right legend of `entries` rows, so that
/// the legend sits over no data in a panel `panel_px` high.
fn above_the_data(y: Range<f64>, entries: usize, panel_px: u32) -> Range<f64> {
    if entries == 0 {
        return y;
    }
    // Each row is a small label and its gap; the box has a margin; the chart leaves room
    // for its x labels and margins.
    let legend_px = (SMALL_TICK_PX + 7) as f64 * entries as f64 + 16.0;
    let plot_px = (panel_px as f64 - 64.0).max(2.0 * legend_px);
    let raise = (y.end - y.start) * legend_px / (plot_px - legend_px);
    y.start..y.end + raise
}

/// The time axis of a whole run: from 0 to its last sample.
fn whole_run(t: &[f64]) -> Range<f64> {
    0.0..t.last().copied().unwrap_or(1.0).max(1e-3)
}

/// `panel` over the times `x` (the samples `t` outside it are the caller's to leave out).
fn draw_line_panel(area: &Area, t: &[f64], x: Range<f64>, panel: &LinePanel) -> DrawResult {
    let values = panel
        .lines
        .iter()
        .flat_map(|(_, v, _, _)| v.iter().copied())
        .chain(panel.marks.iter().map(|m| m.0));
    let y = above_the_data(
        padded_range(values.filter(|v| v.is_finite())),
        panel.lines.iter().filter(|l| !l.0.is_empty()).count(),
        area.dim_in_pixel().1,
    );
    let mut chart = linear_chart(area, x.clone(), y.clone(), ("t (s)", panel.y_desc))?;
    // Inside the panel: plotters does not clip to its chart.
    for (t0, t1) in &panel.spasms {
        if *t1 < x.start || *t0 > x.end {
            continue;
        }
        chart.draw_series(std::iter::once(Rectangle::new(
            [(t0.max(x.start), y.start), (t1.min(x.end), y.end)],
            RGBColor(255, 200, 120).mix(0.35).filled(),
        )))?;
    }
    if let Some((at, label)) = &panel.event {
        // The run ends on the event: its last sample may lie a period before it.
        if *at >= x.start && *at <= x.end + 0.01 * (x.end - x.start) {
            let at = at.min(x.end);
            chart.draw_series(std::iter::once(PathElement::new(
                [(at, y.start), (at, y.end)],
                RED.stroke_width(2),
            )))?;
            chart.draw_series(std::iter::once(Text::new(
                label.clone(),
                (
                    x.start + (x.end - x.start) * 0.005,
                    y.start + 0.06 * (y.end - y.start),
                ),
                (FONT, SMALL_TICK_PX).into_font().color(&RED),
            )))?;
        }
    }
    for (value, label) in &panel.marks {
        chart.draw_series(DashedLineSeries::new(
            [(x.start, *value), (x.end, *value)],
            6,
            4,
            BLACK.mix(0.6).stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            label.clone(),
            (x.start + (x.end - x.start) * 0.005, *value),
            (FONT, SMALL_TICK_PX).into_font(),
        )))?;
    }
    for (label, v, colour, dashed) in &panel.lines {
        // One pixel: a thicker polyline grows miter spikes at the valves' sharp turns.
        let style = colour.stroke_width(1);
        let colour = *colour;
        // Inside the panel: plotters does not clip a line to its chart.
        let (lo, hi) = (y.start, y.end);
        let pts = t
            .iter()
            .zip(v.iter())
            .filter(|(_, b)| b.is_finite())
            .map(move |(a, b)| (*a, b.clamp(lo, hi)));
        let series = if *dashed {
            chart.draw_series(LineSeries::new(pts, colour.mix(0.35).stroke_width(5)))?
        } else {
            chart.draw_series(LineSeries::new(pts, style))?
        };
        series
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(3)));
    }
    if panel.lines.iter().all(|(label, ..)| label.is_empty()) {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font((FONT, SMALL_TICK_PX))
        .draw()?;
    Ok(())
}

/// One line per muscle of `values` (its name, colours after the joints').
fn muscle_lines<'a>(
    tr: &LegTrace,
    values: &'a [Vec<f64>; 4],
    first: usize,
) -> Vec<(String, &'a [f64], RGBColor, bool)> {
    values
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let name = tr.muscles.get(i).cloned().unwrap_or_default();
            (name, tail(v, first), colour(i + 2), false)
        })
        .collect()
}

/// `v` from sample `first` on (empty if it has fewer).
fn tail(v: &[f64], first: usize) -> &[f64] {
    &v[first.min(v.len())..]
}

/// A run longer than this many strides is drawn by its last [`TIME_VIEW_STRIDES`]: 36
/// strides squeezed into a panel leave a solid block of pressure lines.
const TIME_VIEW_MAX_STRIDES: f64 = 6.0;
/// Strides the time view of a long run shows.
const TIME_VIEW_STRIDES: f64 = 4.0;

/// The part of a run the time view draws: the first sample drawn, the time axis, and the
/// caption that says so (none when the whole run is drawn).
fn time_window(t: &[f64], stride_s: f64) -> (usize, Range<f64>, Option<String>) {
    let whole = whole_run(t);
    if stride_s <= 0.0 || whole.end <= TIME_VIEW_MAX_STRIDES * stride_s {
        return (0, whole, None);
    }
    let start = whole.end - TIME_VIEW_STRIDES * stride_s;
    let caption = format!(
        "the last {TIME_VIEW_STRIDES} strides ({start:.1}-{:.1} s) of a {:.1} s run; every stride in strides.png",
        whole.end, whole.end
    );
    (
        t.partition_point(|t| *t < start),
        start..whole.end,
        Some(caption),
    )
}

/// `simulate --plot`: joint angles over their references, tracking errors, the four
/// pressures against the valve's limit, the forces against the rating, and the torques on
/// the limb (the device's, and the patient's unless passive), spasms shaded; on a treadmill also the
/// vertical ground reaction of every foot against the unsupported weight and the
/// pelvis's height. A run of more than [`TIME_VIEW_MAX_STRIDES`] strides is drawn by its
/// last [`TIME_VIEW_STRIDES`], each panel's caption saying so.
pub fn leg_run(path: &Path, title: &str, setting: &str, tr: &LegTrace) -> DrawResult {
    let (first, x, caption) = time_window(&tr.t_s, tr.stride_s);
    let event = tr
        .collapse_s
        .map(|t| (t, format!("collapse at {t:.2} s: the trainer stopped")));
    let spasms = |j: Option<usize>| -> Vec<(f64, f64)> {
        tr.spasms
            .iter()
            .filter(|(sj, ..)| j.is_none_or(|j| *sj == j))
            .map(|(_, a, b)| (*a, *b))
            .collect()
    };
    let reference = tr.reference_deg.each_ref().map(|v| tail(v, first));
    let angle = tr.angle_deg.each_ref().map(|v| tail(v, first));
    let errors: [Vec<f64>; 2] = std::array::from_fn(|j| {
        reference[j]
            .iter()
            .zip(angle[j])
            .map(|(r, a)| r - a)
            .collect()
    });
    let joint_panel = |j: usize, name: &'static str| LinePanel {
        y_desc: if j == 0 {
            "hip flexion (deg)"
        } else {
            "knee flexion (deg)"
        },
        lines: vec![
            (
                format!("{name} reference"),
                reference[j],
                REFERENCE_GREY,
                true,
            ),
            (format!("{name} angle"), angle[j], colour(j), false),
        ],
        marks: Vec::new(),
        spasms: spasms(Some(j)),
        event: event.clone(),
    };
    let mut panels = vec![
        joint_panel(0, "hip"),
        joint_panel(1, "knee"),
        LinePanel {
            y_desc: "tracking error (deg)",
            lines: vec![
                ("hip".into(), &errors[0][..], colour(0), false),
                ("knee".into(), &errors[1][..], colour(1), false),
            ],
            marks: Vec::new(),
            spasms: spasms(None),
            event: event.clone(),
        },
    ];
    // The torques on the limb: the device's always, the patient's unless passive (zero
    // throughout, no lines of nothing).
    let active = tr.patient_nm.iter().flatten().any(|v| *v != 0.0);
    let mut torques: Vec<(String, &[f64], RGBColor, bool)> = Vec::new();
    for (who, series, dashed, shown) in [
        ("patient", &tr.patient_nm, false, active),
        ("device on the limb", &tr.interaction_nm, true, true),
    ] {
        if shown {
            for (j, name) in ["hip", "knee"].iter().enumerate() {
                torques.push((
                    format!("{who}, {name}"),
                    tail(&series[j], first),
                    colour(j),
                    dashed,
                ));
            }
        }
    }
    panels.push(LinePanel {
        y_desc: "torque on the limb (N m, flexion +)",
        lines: torques,
        marks: Vec::new(),
        spasms: spasms(None),
        event: event.clone(),
    });
    panels.push(LinePanel {
        y_desc: "cuff force on the limb (N, forward +)",
        lines: ["thigh cuff", "shank cuff"]
            .iter()
            .enumerate()
            .map(|(i, name)| {
                (
                    (*name).into(),
                    tail(&tr.cuff_force_n[i], first),
                    colour(i),
                    true,
                )
            })
            .collect(),
        marks: Vec::new(),
        spasms: spasms(None),
        event: event.clone(),
    });
    panels.push(LinePanel {
        y_desc: "pressure (bar)",
        lines: muscle_lines(tr, &tr.pressure_bar, first),
        marks: vec![
            (tr.pressure_max_bar, "valve limit".into()),
            (0.0, "vented".into()),
        ],
        spasms: spasms(None),
        event: event.clone(),
    });
    panels.push(LinePanel {
        y_desc: "force (N)",
        lines: muscle_lines(tr, &tr.force_n, first),
        marks: vec![(tr.rated_force_n, "rated force".into())],
        spasms: spasms(None),
        event: event.clone(),
    });
    if let Some(g) = &tr.ground {
        let mut lines: Vec<(String, &[f64], RGBColor, bool)> = g
            .foot_n
            .iter()
            .enumerate()
            .map(|(leg, f)| {
                let name = if tr.legs > 1 {
                    format!("{} foot", pma_leg::SIDES[leg])
                } else {
                    "this foot".into()
                };
                (name, tail(f, first), colour(leg), false)
            })
            .collect();
        if g.other_leg_n.iter().any(|f| *f != 0.0) {
            lines.push((
                "the virtual other leg".into(),
                tail(&g.other_leg_n, first),
                colour(2),
                false,
            ));
        }
        panels.push(LinePanel {
            y_desc: "vertical ground reaction (N)",
            lines,
            marks: vec![(g.unsupported_n, "(1 - bws) m g".into())],
            spasms: spasms(None),
            event: event.clone(),
        });
        panels.push(LinePanel {
            y_desc: "pelvis height (m)",
            lines: vec![("pelvis".into(), tail(&g.pelvis_m, first), colour(2), false)],
            marks: Vec::new(),
            spasms: spasms(None),
            event: event.clone(),
        });
    }
    let row_count = panels.len().div_ceil(2);
    let root = BitMapBackend::new(path, (1400, 100 + 400 * row_count as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let t = tail(&tr.t_s, first);
    for (area, panel) in body.split_evenly((row_count, 2)).iter().zip(&panels) {
        match &caption {
            Some(c) => {
                let area = area.titled(c, (FONT, SMALL_TICK_PX + 1))?;
                draw_line_panel(&area, t, x.clone(), panel)?;
            }
            None => draw_line_panel(area, t, x.clone(), panel)?,
        }
    }
    root.present()?;
    Ok(())
}

/// The normative vertical ground reaction a foot's is drawn against (body weights, 101
/// samples at 0, 1, ..., 100 % of the cycle), already scaled as its label says.
#[derive(Debug, Clone)]
pub struct NormGrf {
    /// Mean.
    pub mean_bw: Vec<f64>,
    /// Standard deviation over the subjects.
    pub sd_bw: Vec<f64>,
    /// What it is and how it is scaled, for the legend.
    pub label: String,
}

/// What `strides.png` draws: every leg over its gait cycle, and on a treadmill the
/// normative ground reaction.
pub struct StrideFigure<'a> {
    /// The run's legs, binned.
    pub cycles: &'a pma_exo::strides::GaitCycles,
    /// On a treadmill with the adult reference.
    pub norm_grf: Option<NormGrf>,
    /// Whether the feet were on a treadmill (a ground-reaction panel per leg).
    pub treadmill: bool,
}

/// One panel of `strides.png`: a channel's mean over the strides and their range, with
/// the reference's curve (binned as the run's) or a norm, and the reference's toe-off.
struct CyclePanel<'a> {
    caption: String,
    y_desc: &'static str,
    curve: &'a pma_exo::strides::CycleCurve,
    colour: RGBColor,
    reference: Option<&'a pma_exo::strides::CycleCurve>,
    norm: Option<&'a NormGrf>,
    /// A zero line (tracking errors).
    zero: bool,
    toe_off_pct: f64,
}

/// Size of one panel of `strides.png` (px).
const CYCLE_CELL: (u32, u32) = (500, 330);

/// The size of `strides.png` for `legs` legs, with or without a treadmill: a column per
/// joint (hip, knee, and on a treadmill the ankle above the foot's ground reaction), two
/// rows per leg, a legend column.
pub fn strides_size(legs: usize, treadmill: bool) -> (u32, u32) {
    let cols = if treadmill { 3 } else { 2 };
    (
        LEGEND_WIDTH + CYCLE_CELL.0 * cols,
        TITLE_HEIGHT + CYCLE_CELL.1 * 2 * legs.max(1) as u32,
    )
}

/// Percent of the cycle of each bin's centre.
fn bin_pct(bin: usize) -> f64 {
    100.0 * pma_exo::strides::bin_centre(bin)
}

fn draw_cycle_panel(area: &Area, p: &CyclePanel) -> DrawResult {
    use pma_exo::strides::BINS;
    let area = area.titled(&p.caption, (FONT, AXIS_DESC_PX))?;
    let curves = std::iter::once(p.curve).chain(p.reference);
    let run_values = curves.flat_map(|c| {
        (0..BINS).flat_map(move |b| {
            let (lo, hi) = c.range(b);
            [c.mean(b), lo, hi]
        })
    });
    let norm_values = p.norm.into_iter().flat_map(|n| {
        n.mean_bw
            .iter()
            .zip(&n.sd_bw)
            .flat_map(|(m, sd)| [m - sd, m + sd])
    });
    let zero = p.zero.then_some(0.0);
    let y = padded_range(
        run_values
            .chain(norm_values)
            .chain(zero)
            .filter(|v| v.is_finite()),
    );
    let x_desc = "gait cycle (% from initial contact)";
    let mut chart = linear_chart(&area, 0.0..100.0, y.clone(), (x_desc, p.y_desc))?;
    if let Some(n) = p.norm {
        let pct = |k: usize| 100.0 * k as f64 / (n.mean_bw.len().max(2) - 1) as f64;
        let band = band_polygon(
            (0..n.mean_bw.len())
                .map(|k| (pct(k), n.mean_bw[k] - n.sd_bw[k], n.mean_bw[k] + n.sd_bw[k])),
        );
        chart.draw_series(std::iter::once(Polygon::new(band, NORM_BAND.filled())))?;
        let mean = (0..n.mean_bw.len()).map(|k| (pct(k), n.mean_bw[k]));
        chart.draw_series(LineSeries::new(mean, BLACK.stroke_width(1)))?;
    }
    if p.zero {
        chart.draw_series(LineSeries::new(
            [(0.0, 0.0), (100.0, 0.0)],
            BLACK.mix(0.5).stroke_width(1),
        ))?;
    }
    if let Some(r) = p.reference {
        let line = (0..BINS)
            .map(|b| (bin_pct(b), r.mean(b)))
            .filter(|(_, v)| v.is_finite());
        chart.draw_series(LineSeries::new(
            line,
            REFERENCE_GREY.stroke_width(REFERENCE_PX),
        ))?;
    }
    let band = band_polygon((0..BINS).map(|b| {
        let (lo, hi) = p.curve.range(b);
        (bin_pct(b), lo, hi)
    }));
    let style = p.colour.mix(0.25).filled();
    chart.draw_series(std::iter::once(Polygon::new(band, style)))?;
    let mean = (0..BINS)
        .map(|b| (bin_pct(b), p.curve.mean(b)))
        .filter(|(_, v)| v.is_finite());
    chart.draw_series(LineSeries::new(mean, p.colour.stroke_width(LINE_PX)))?;
    chart.draw_series(DashedLineSeries::new(
        [(p.toe_off_pct, y.start), (p.toe_off_pct, y.end)],
        5,
        4,
        BLACK.mix(0.5).stroke_width(1),
    ))?;
    Ok(())
}

/// The normative band: light enough that the run's band shows over it.
const NORM_BAND: RGBColor = RGBColor(225, 225, 225);

/// The outline of a band through `(x, low, high)`: along the highs, back along the lows
/// (bins without a value left out).
fn band_polygon(points: impl Iterator<Item = (f64, f64, f64)>) -> Vec<(f64, f64)> {
    let points: Vec<(f64, f64, f64)> = points
        .filter(|(_, lo, hi)| lo.is_finite() && hi.is_finite())
        .collect();
    let upper = points.iter().map(|(x, _, hi)| (*x, *hi));
    let lower = points.iter().rev().map(|(x, lo, _)| (*x, *lo));
    upper.chain(lower).collect()
}

/// `simulate --plot`'s `strides.png`: for every leg, its hip and knee (and on a treadmill
/// its passive ankle) over the gait cycle, 0 % at the leg's initial contact in its gait
/// reference ([`pma_leg::gait::GaitReference::phase`]): the mean over the strides after
/// the first and the range of the strides' own means, over the reference binned the
/// same way; the tracking errors likewise; on a treadmill each foot's vertical ground
/// reaction in body weights against the normative curve. Legends in a column of their
/// own.
pub fn strides_run(path: &Path, title: &str, setting: &str, fig: &StrideFigure) -> DrawResult {
    let legs = fig.cycles.legs();
    let size = strides_size(legs.len(), fig.treadmill);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (grid, legend) = body.split_horizontally(size.0 - LEGEND_WIDTH);
    let cols = if fig.treadmill { 3 } else { 2 };
    let cells = grid.split_evenly((2 * legs.len().max(1), cols));
    for (leg, cycle) in legs.iter().enumerate() {
        let side = if legs.len() > 1 {
            format!("{} ", pma_leg::SIDES[leg])
        } else {
            String::new()
        };
        let toe_off_pct = 100.0 * cycle.gait().toe_off_phase();
        let panel = |caption: String, y_desc, curve, colour, reference| CyclePanel {
            caption,
            y_desc,
            curve,
            colour,
            reference,
            norm: None,
            zero: false,
            toe_off_pct,
        };
        let mut panels: Vec<(usize, CyclePanel)> = Vec::new();
        for (j, name) in ["hip", "knee"].into_iter().enumerate() {
            panels.push((
                j,
                panel(
                    format!("{side}{name}: flexion"),
                    "angle (deg, flexion +)",
                    &cycle.angle_deg[j],
                    colour(j),
                    Some(&cycle.reference_deg[j]),
                ),
            ));
            panels.push((
                cols + j,
                CyclePanel {
                    zero: true,
                    ..panel(
                        format!("{side}{name}: tracking error"),
                        "reference - angle (deg)",
                        &cycle.error_deg[j],
                        colour(j),
                        None,
                    )
                },
            ));
        }
        if cycle.has_ankle() {
            panels.push((
                2,
                panel(
                    format!("{side}ankle (passive): dorsiflexion"),
                    "angle (deg, dorsiflexion +)",
                    &cycle.angle_deg[2],
                    colour(2),
                    Some(&cycle.reference_deg[2]),
                ),
            ));
        }
        if fig.treadmill {
            panels.push((
                cols + 2,
                CyclePanel {
                    norm: fig.norm_grf.as_ref(),
                    ..panel(
                        format!("{side}foot: vertical ground reaction"),
                        "vertical GRF (body weights)",
                        &cycle.grf_bw,
                        colour(4),
                        None,
                    )
                },
            ));
        }
        for (cell, p) in &panels {
            if let Some(area) = cells.get(2 * cols * leg + cell) {
                draw_cycle_panel(area, p)?;
            }
        }
    }
    legend_column(&legend, &strides_legend_title(fig), &strides_legend(fig))?;
    root.present()?;
    Ok(())
}

/// How the cycle is cut and how many strides each leg contributes.
fn strides_legend_title(fig: &StrideFigure) -> String {
    let span = fig.cycles.span_s();
    let text = format!(
        "0 % of the cycle: each leg's initial contact in its gait reference; 1 % bins; the {:.1} strides after the first ({:.2}-{:.2} s)",
        fig.cycles.strides(),
        span.start,
        span.end
    );
    wrapped(&text, LEGEND_CHARS + 4).join("\n")
}

/// The legend of `strides.png`: what each line and band is.
fn strides_legend(fig: &StrideFigure) -> Vec<LegendEntry> {
    let mut entries = vec![
        LegendEntry {
            label: "reference, binned as the run".into(),
            style: REFERENCE_GREY.stroke_width(REFERENCE_PX),
        },
        LegendEntry {
            label: "hip: mean over the strides".into(),
            style: colour(0).stroke_width(3),
        },
        LegendEntry {
            label: "knee: mean over the strides".into(),
            style: colour(1).stroke_width(3),
        },
    ];
    if fig.cycles.legs().iter().any(|c| c.has_ankle()) {
        entries.push(LegendEntry {
            label: "ankle: mean over the strides".into(),
            style: colour(2).stroke_width(3),
        });
    }
    if fig.treadmill {
        entries.push(LegendEntry {
            label: "foot: mean over the strides".into(),
            style: colour(4).stroke_width(3),
        });
    }
    entries.push(LegendEntry {
        label: "band: range (min-max) of the strides' means".into(),
        style: BLACK.mix(0.25).stroke_width(12),
    });
    if let Some(n) = &fig.norm_grf {
        entries.push(LegendEntry {
            label: n.label.clone(),
            style: BLACK.stroke_width(1),
        });
        entries.push(LegendEntry {
            label: "band: ±1 SD over the subjects, scaled alike".into(),
            style: NORM_BAND.stroke_width(12),
        });
    }
    entries.push(LegendEntry {
        label: "vertical line: the reference's toe-off".into(),
        style: BLACK.mix(0.5).stroke_width(1),
    });
    entries
}

/// The pendulum test's figures for `pendulum --plot`.
#[derive(Debug, Clone, Copy)]
pub struct PendulumMarks {
    /// Knee at release, first flexion peak and rest (deg).
    pub start_deg: f64,
    /// First flexion peak (deg).
    pub first_peak_deg: f64,
    /// Resting angle (deg).
    pub rest_deg: f64,
    /// R2 = (start - first peak) / (start - rest), if the knee came to rest.
    pub r2: Option<f64>,
}

/// `pendulum --plot`: the knee released from its start angle, with R2's construction (the
/// release, first-peak and rest angles as marks), and the patient's knee torque.
pub fn pendulum_run(
    path: &Path,
    title: &str,
    setting: &str,
    tr: &LegTrace,
    m: &PendulumMarks,
) -> DrawResult {
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let rows = body.split_evenly((2, 1));
    let r2 =
        m.r2.map_or("R2: the knee has not come to rest".to_owned(), |r| {
            format!("R2 = (start - first peak) / (start - rest) = {r:.3}")
        });
    let panels = [
        LinePanel {
            y_desc: "knee flexion (deg)",
            lines: vec![(r2, &tr.angle_deg[1][..], colour(1), false)],
            marks: vec![
                (m.start_deg, format!("release {:.1} deg", m.start_deg)),
                (
                    m.first_peak_deg,
                    format!("first peak {:.1} deg", m.first_peak_deg),
                ),
                (m.rest_deg, format!("rest {:.1} deg", m.rest_deg)),
            ],
            spasms: Vec::new(),
            event: None,
        },
        LinePanel {
            y_desc: "patient knee torque (N m, flexion +)",
            lines: vec![(
                "reflex and stiffness".into(),
                &tr.patient_nm[1][..],
                colour(0),
                false,
            )],
            marks: vec![(0.0, String::new())],
            spasms: Vec::new(),
            event: None,
        },
    ];
    for (area, panel) in rows.iter().zip(&panels) {
        draw_line_panel(area, &tr.t_s, whole_run(&tr.t_s), panel)?;
    }
    root.present()?;
    Ok(())
}

/// One panel of grouped bars: `values[group][member]` (NaN: nothing to show).
pub struct BarPanel {
    /// Axis description.
    pub y_desc: String,
    /// Values by group, then member.
    pub values: Vec<Vec<f64>>,
}

/// Grouped bars, one panel per metric in a 2-column grid: `groups` along x (scenarios),
/// one bar per member (controller) in each, a shared legend.
pub fn grouped_bars(
    path: &Path,
    title: &str,
    setting: &str,
    groups: &[String],
    members: &[String],
    panels: &[BarPanel],
) -> DrawResult {
    let rows = panels.len().div_ceil(2).max(1);
    let root = BitMapBackend::new(path, (1400, 120 + 380 * rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (grid, legend) = body.split_horizontally(1400 - LEGEND_WIDTH);
    let areas = grid.split_evenly((rows, 2));
    let n = members.len().max(1) as f64;
    for (area, panel) in areas.iter().zip(panels) {
        let top = panel
            .values
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max);
        // All zero: a unit axis, not ticks of 1e-9.
        let top = if top > 0.0 { top * 1.1 } else { 1.0 };
        let x_max = groups.len() as f64;
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..x_max, 0.0..top)?;
        let names = groups.to_vec();
        let x_fmt = move |v: &f64| {
            let k = v.floor() as usize;
            if (v - k as f64 - 0.5).abs() < 1e-6 {
                names.get(k).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        let span = top;
        let y_fmt = move |v: &f64| tick_label(*v, span);
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(2 * groups.len() + 1)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .y_desc(panel.y_desc.as_str())
            .label_style((FONT, TICK_PX))
            .axis_desc_style((FONT, AXIS_DESC_PX))
            .bold_line_style(BLACK.mix(0.15))
            .light_line_style(BLACK.mix(0.04))
            .draw()?;
        for (g, values) in panel.values.iter().enumerate() {
            for (m, v) in values.iter().enumerate() {
                if !v.is_finite() {
                    continue;
                }
                let x0 = g as f64 + 0.1 + 0.8 * m as f64 / n;
                let x1 = x0 + 0.8 / n * 0.9;
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x0, 0.0), (x1, *v)],
                    colour(m).filled(),
                )))?;
            }
        }
    }
    let entries: Vec<(String, RGBColor)> = members
        .iter()
        .enumerate()
        .map(|(m, name)| (name.clone(), colour(m)))
        .collect();
    let style = (FONT, LEGEND_PX).into_font();
    for (k, (name, c)) in entries.iter().enumerate() {
        let y = 40 + 28 * k as i32;
        legend.draw(&Rectangle::new([(10, y), (34, y + 16)], c.filled()))?;
        legend.draw(&Text::new(name.clone(), (42, y), style.clone()))?;
    }
    root.present()?;
    Ok(())
}

/// Tracking errors over time, one panel per `(caption, runs)` cell in `cols` columns, each
/// run a line coloured by its place in the cell (the same controllers in every cell):
/// the paper's Fig. 9 layout.
pub fn error_grid(
    path: &Path,
    title: &str,
    setting: &str,
    cells: &[(String, Vec<pma_studies::sweep::Trace>)],
    cols: usize,
) -> DrawResult {
    let cols = cols.max(1);
    let rows = cells.len().div_ceil(cols).max(1);
    let root = BitMapBackend::new(path, (1400, 120 + 300 * rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(TITLE_HEIGHT);
    title_block(&head, title, setting)?;
    let (grid, legend) = body.split_horizontally(1400 - LEGEND_WIDTH);
    for (area, (caption, runs)) in grid.split_evenly((rows, cols)).iter().zip(cells) {
        let area = area.titled(caption, (FONT, AXIS_DESC_PX))?;
        let errors: Vec<Vec<f64>> = runs
            .iter()
            .map(|r| {
                r.reference_m
                    .iter()
                    .zip(&r.position_m)
                    .map(|(d, x)| (d - x) * 1e3)
                    .collect()
            })
            .collect();
        let t = runs.first().map_or(&[][..], |r| &r.t_s[..]);
        let panel = LinePanel {
            y_desc: "e = x_d - x (mm)",
            lines: errors
                .iter()
                .enumerate()
                .map(|(k, e)| (String::new(), &e[..], colour(k), false))
                .collect(),
            marks: Vec::new(),
            spasms: Vec::new(),
            event: None,
        };
        draw_line_panel(&area, t, whole_run(t), &panel)?;
    }
    let entries: Vec<LegendEntry> = cells
        .first()
        .map(|(_, runs)| &runs[..])
        .unwrap_or_default()
        .iter()
        .enumerate()
        .map(|(k, r)| LegendEntry {
            label: r.label.clone(),
            style: colour(k).stroke_width(3),
        })
        .collect();
    legend_column(&legend, "controller", &entries)?;
    root.present()?;
    Ok(())
}
