use crate::plot::DrawResult;
use crate::plot::*;
use plotters::prelude::*;
use std::path::Path;

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
