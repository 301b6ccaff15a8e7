//! What every figure shares (plotters, bitmap backend, the embedded DejaVu Sans): the
//! font, sizes, palette, axes, tick labels, legends and line panels; and the two figure
//! kinds several commands draw (a bench run's tracking, `paper` and `rig commission`;
//! distributions over runs, `paper` and `sweep`). A figure only one command draws lives
//! with that command (`commands/simulate/figures.rs`, ...).
//!
//! A tracking figure is 1200 x 800: two title lines (the experiment; reference, plant and
//! duration), the trajectories over their reference(s), then the tracking errors. Runs of
//! one controller with one setting varied share a signed error panel; runs of different
//! controllers, whose errors span decades, get one log-scale panel each so that no run's
//! error sets the scale of the others. Legends sit in a column of their own, off the data.
mod distributions;
mod tracking;

pub use distributions::{leg_rms_distributions, rte_distributions};
pub use tracking::draw;

use anyhow::Result;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use pma_studies::experiments::Series;
use std::ops::Range;

/// Registers the embedded DejaVu Sans as plotters' `sans-serif`.
pub fn register_font() -> Result<()> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
    )
    .map_err(|_| anyhow::anyhow!("the embedded DejaVuSans.ttf is not a valid font"))
}

/// A drawing step's result.
pub type DrawOutcome<T> = std::result::Result<T, Box<dyn std::error::Error + Send + Sync>>;

/// A drawing's result.
pub type DrawResult = DrawOutcome<()>;

pub(crate) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

pub(crate) type LinearChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

pub(crate) const SIZE: (u32, u32) = (1200, 800);

pub(crate) const FONT: &str = "sans-serif";

pub(crate) const TITLE_PX: u32 = 26;

pub(crate) const SETTING_PX: u32 = 18;

pub(crate) const AXIS_DESC_PX: u32 = 17;

pub(crate) const TICK_PX: u32 = 15;

pub(crate) const SMALL_TICK_PX: u32 = 13;

pub(crate) const LEGEND_PX: u32 = 16;

pub(crate) const TITLE_HEIGHT: u32 = 72;

pub(crate) const LEGEND_WIDTH: u32 = 240;

pub(crate) const LINE_PX: u32 = 2;

pub(crate) const REFERENCE_PX: u32 = 7;

/// The reference: a light grey band under the runs, so that a run that tracks it well
/// shows as a coloured line inside it and a run that does not leaves it. Opaque, so the
/// identical references of several runs do not darken where they overlap.
pub(crate) const REFERENCE_GREY: RGBColor = RGBColor(200, 200, 200);

/// Run colours: Tableau 10 (classic) without its olive, which reads as yellow on white,
/// and with its grey after them, since the reference band is grey (only a ninth run gets
/// it); then dark hues for the groups of a sweep (a leg sweep's controllers times patient
/// groups reach ten).
pub(crate) const PALETTE: [RGBColor; 14] = [
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
pub(crate) fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// The experiment on the first line, its conditions on the second, centred.
pub(crate) fn title_block(area: &Area, title: &str, setting: &str) -> DrawResult {
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

/// The smallest and largest of `values`, widened by 5 % on each side.
pub(crate) fn padded_range(values: impl Iterator<Item = f64>) -> Range<f64> {
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
pub(crate) fn tick_label(v: f64, span: f64) -> String {
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

/// A linear chart on `area` with readable tick labels and axis descriptions.
pub(crate) fn linear_chart<'a, 'b>(
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
pub(crate) fn points<'s>(
    t: &'s [f64],
    v: &'s [f64],
    scale: f64,
) -> impl Iterator<Item = (f64, f64)> + Clone + 's {
    t.iter().zip(v).map(move |(t, v)| (*t, v * scale))
}

/// A dashed grey vertical line and its label at each event.
pub(crate) fn event_markers(
    chart: &mut LinearChart,
    events: &[(f64, String)],
    y: Range<f64>,
) -> DrawResult {
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

/// One legend row: a line sample and its label.
pub(crate) struct LegendEntry {
    pub(crate) label: String,
    pub(crate) style: ShapeStyle,
}

/// The reference band first, then the runs.
pub(crate) fn legend_entries(series: &[Series], (one, each): (&str, &str)) -> Vec<LegendEntry> {
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
pub(crate) fn legend_column(area: &Area, title: &str, entries: &[LegendEntry]) -> DrawResult {
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
pub(crate) const LEGEND_CHARS: usize = 19;

/// `label` in lines of at most `width` characters, broken before ` (`, `+`, `@` or a space
/// (a word longer than `width` stays whole): a legend never runs off the picture.
pub(crate) fn wrapped(label: &str, width: usize) -> Vec<String> {
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
pub(crate) fn legend_sample(area: &Area, (x, y): (i32, i32), e: &LegendEntry) -> DrawResult {
    area.draw(&PathElement::new(vec![(x, y), (x + 36, y)], e.style))?;
    Ok(())
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

/// Dash patterns (on, off in pixels) of a second factor, solid first; and their names.
pub(crate) const DASHES: [Option<(u32, u32)>; 4] =
    [None, Some((10, 5)), Some((3, 4)), Some((14, 4))];

pub(crate) const DASH_NAMES: [&str; 4] = ["solid", "dashed", "dotted", "long dashes"];

/// Whether every run tracks the same reference (the legend then names one).
pub(crate) fn shared_reference(series: &[Series]) -> bool {
    series
        .windows(2)
        .all(|w| w[0].reference_m == w[1].reference_m)
}

/// One panel of lines over time with dashed horizontal marks and shaded spasms.
pub(crate) struct LinePanel<'a> {
    pub(crate) y_desc: &'a str,
    pub(crate) lines: Vec<(String, &'a [f64], RGBColor, bool)>,
    pub(crate) marks: Vec<(f64, String)>,
    pub(crate) spasms: Vec<(f64, f64)>,
    /// A moment marked by a vertical line and its label (a collapse the trainer stopped).
    pub(crate) event: Option<(f64, String)>,
}

/// `y` raised at the top by the height of an upper-right legend of `entries` rows, so that
/// the legend sits over no data in a panel `panel_px` high.
pub(crate) fn above_the_data(y: Range<f64>, entries: usize, panel_px: u32) -> Range<f64> {
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
pub(crate) fn whole_run(t: &[f64]) -> Range<f64> {
    0.0..t.last().copied().unwrap_or(1.0).max(1e-3)
}

/// `panel` over the times `x` (the samples `t` outside it are the caller's to leave out).
pub(crate) fn draw_line_panel(
    area: &Area,
    t: &[f64],
    x: Range<f64>,
    panel: &LinePanel,
) -> DrawResult {
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
            // A wide line as separate segments: a wide polyline's miter joins at sharp
            // turns grow spikes that reach into the next panel (issue 49); segments have
            // no joins.
            let pts: Vec<(f64, f64)> = pts.collect();
            let wide = colour.mix(0.35).stroke_width(5);
            chart.draw_series(
                pts.windows(2)
                    .map(move |w| PathElement::new(vec![w[0], w[1]], wide)),
            )?
        } else {
            chart.draw_series(LineSeries::new(pts, style))?
        };
        // The legend draws each line as the panel does: wide and pale, or thin.
        let key = if *dashed {
            colour.mix(0.35).stroke_width(6)
        } else {
            colour.stroke_width(2)
        };
        series
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], key));
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
    fn regression_a_wide_line_stays_inside_its_panel() {
        // leg.png's wide cuff-force trace, a zigzag between its range's ends every sample,
        // grew miter spikes hundreds of pixels into the panels above and below. Drawn in
        // the lower of two panels, none of its pixels may land in the upper one.
        register_font().unwrap();
        let (w, h) = (400u32, 400u32);
        let mut buf = vec![0u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            let (_, lower) = root.split_vertically(h / 2);
            let t: Vec<f64> = (0..400).map(|k| f64::from(k) * 0.01).collect();
            let v: Vec<f64> = (0..400)
                .map(|k| if k % 2 == 0 { -600.0 } else { 600.0 })
                .collect();
            let panel = LinePanel {
                y_desc: "force (N)",
                lines: vec![(String::new(), &v, RGBColor(31, 119, 180), true)],
                marks: Vec::new(),
                spasms: Vec::new(),
                event: None,
            };
            draw_line_panel(&lower, &t, 0.0..4.0, &panel).unwrap();
            root.present().unwrap();
        }
        let upper = &buf[..(w * (h / 2) * 3) as usize];
        let stray = upper.chunks(3).filter(|p| p != &[255, 255, 255]).count();
        assert_eq!(
            stray, 0,
            "{stray} pixels of the lower panel's line in the upper one"
        );
    }

    #[test]
    fn ticks_never_print_negative_zero() {
        assert_eq!(tick_label(-0.0, 1.0), "0");
        assert_eq!(tick_label(-1e-12, 1.0), "0");
        assert_eq!(tick_label(0.2, 1.8), "0.2");
        assert_eq!(tick_label(-0.25, 1.8), "-0.25");
        assert_eq!(tick_label(20.0, 20.0), "20");
    }
}
