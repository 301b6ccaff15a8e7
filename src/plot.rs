//! The PNG plots of `paper` (plotters, bitmap backend, the embedded DejaVu Sans).
use anyhow::Result;
use plotters::prelude::*;
use pma_sim::experiments::Series;
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

/// A drawing's result.
pub type DrawResult = std::result::Result<(), Box<dyn std::error::Error + Send + Sync>>;

/// Two panels: reference and positions (mm) over time, and tracking errors (mm).
pub fn tracking(path: &Path, title: &str, series: &[Series]) -> DrawResult {
    let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 24))?;
    let (top, bottom) = root.split_vertically(440);
    let t_max = series
        .iter()
        .filter_map(|s| s.t_s.last().copied())
        .fold(1.0, f64::max);
    let mm = |v: f64| v * 1e3;
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    let (mut elo, mut ehi) = (f64::MAX, f64::MIN);
    for s in series {
        for (r, x) in s.reference_m.iter().zip(&s.position_m) {
            lo = lo.min(mm(*r)).min(mm(*x));
            hi = hi.max(mm(*r)).max(mm(*x));
            let e = mm(r - x);
            elo = elo.min(e);
            ehi = ehi.max(e);
        }
    }
    let pad = |a: f64, b: f64| {
        let p = ((b - a) * 0.05).max(1e-3);
        (a - p, b + p)
    };
    let (lo, hi) = pad(lo, hi);
    let (elo, ehi) = pad(elo, ehi);
    let mut c = ChartBuilder::on(&top)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, lo..hi)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .y_desc("contraction (mm)")
        .draw()?;
    if let Some(s0) = series.first() {
        c.draw_series(LineSeries::new(
            s0.t_s
                .iter()
                .zip(&s0.reference_m)
                .map(|(t, r)| (*t, mm(*r))),
            BLACK.stroke_width(2),
        ))?
        .label("reference")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    }
    for (i, s) in series.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        c.draw_series(LineSeries::new(
            s.t_s.iter().zip(&s.position_m).map(|(t, x)| (*t, mm(*x))),
            col,
        ))?
        .label(s.label.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    let mut e = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, elo..ehi)?;
    e.configure_mesh()
        .x_desc("t (s)")
        .y_desc("error x_d - x (mm)")
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        e.draw_series(LineSeries::new(
            s.t_s
                .iter()
                .zip(s.reference_m.iter().zip(&s.position_m))
                .map(|(t, (r, x))| (*t, mm(r - x))),
            col,
        ))?;
    }
    root.present()?;
    Ok(())
}
