use super::DrawResult;
use super::*;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use pma_studies::experiments::paper::{Plot, Varied};
use pma_studies::experiments::Series;
use std::path::Path;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decades_carry_their_unit() {
        assert_eq!(decade_label(1e-8), "10 nm");
        assert_eq!(decade_label(1e-6), "1 µm");
        assert_eq!(decade_label(1e-4), "100 µm");
        assert_eq!(decade_label(1e-2), "10 mm");
        assert_eq!(decade_label(0.1), "100 mm");
    }
}
