use crate::plot::DrawResult;
use crate::plot::*;
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

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
