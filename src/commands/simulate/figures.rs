use crate::plot::DrawResult;
use crate::plot::*;
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

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
    let w = Window {
        tr,
        first,
        event: tr
            .collapse_s
            .map(|t| (t, format!("collapse at {t:.2} s: the trainer stopped"))),
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
    let mut panels = joint_panels(&w, reference, angle, &errors);
    panels.extend(limb_panels(&w));
    panels.extend(ground_panels(&w));
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

/// The part of a leg run `leg.png` draws: from sample `first` on, with the collapse (if
/// any) marked in every panel.
struct Window<'a> {
    tr: &'a LegTrace,
    first: usize,
    event: Option<(f64, String)>,
}

impl<'a> Window<'a> {
    /// The spasms of joint `j` (every joint's: `None`) as shaded spans.
    fn spasms(&self, j: Option<usize>) -> Vec<(f64, f64)> {
        self.tr
            .spasms
            .iter()
            .filter(|(sj, ..)| j.is_none_or(|j| *sj == j))
            .map(|(_, a, b)| (*a, *b))
            .collect()
    }

    /// A panel of `lines` with `marks`, shaded where joint `j`'s spasms were.
    fn panel(
        &self,
        y_desc: &'a str,
        lines: Vec<(String, &'a [f64], RGBColor, bool)>,
        marks: Vec<(f64, String)>,
        j: Option<usize>,
    ) -> LinePanel<'a> {
        LinePanel {
            y_desc,
            lines,
            marks,
            spasms: self.spasms(j),
            event: self.event.clone(),
        }
    }
}

/// Hip and knee over their references, and both tracking errors.
fn joint_panels<'a>(
    w: &Window<'a>,
    reference: [&'a [f64]; 2],
    angle: [&'a [f64]; 2],
    errors: &'a [Vec<f64>; 2],
) -> Vec<LinePanel<'a>> {
    let joint_panel = |j: usize, name: &'static str| {
        let y_desc = if j == 0 {
            "hip flexion (deg)"
        } else {
            "knee flexion (deg)"
        };
        let lines = vec![
            (
                format!("{name} reference"),
                reference[j],
                REFERENCE_GREY,
                true,
            ),
            (format!("{name} angle"), angle[j], colour(j), false),
        ];
        w.panel(y_desc, lines, Vec::new(), Some(j))
    };
    let error_lines = vec![
        ("hip".into(), &errors[0][..], colour(0), false),
        ("knee".into(), &errors[1][..], colour(1), false),
    ];
    vec![
        joint_panel(0, "hip"),
        joint_panel(1, "knee"),
        w.panel("tracking error (deg)", error_lines, Vec::new(), None),
    ]
}

/// What acts on the limb: the torques (the device's always, the patient's unless passive:
/// zero throughout, no lines of nothing), the cuffs' forces, the muscles' pressures and
/// forces against their limits.
fn limb_panels<'a>(w: &Window<'a>) -> Vec<LinePanel<'a>> {
    let (tr, first) = (w.tr, w.first);
    let active = tr.patient_nm.iter().flatten().any(|v| *v != 0.0);
    let mut torques: Vec<(String, &[f64], RGBColor, bool)> = Vec::new();
    // The patient's torques in colours of their own: at one joint the patient's and the
    // device's shared a colour, told apart only by the line's width (issue 49).
    for (who, series, dashed, shown, colour_of) in [
        ("patient", &tr.patient_nm, false, active, 2),
        ("device on the limb", &tr.interaction_nm, true, true, 0),
    ] {
        if shown {
            for (j, name) in ["hip", "knee"].iter().enumerate() {
                torques.push((
                    format!("{who}, {name}"),
                    tail(&series[j], first),
                    colour(colour_of + j),
                    dashed,
                ));
            }
        }
    }
    let cuffs = ["thigh cuff", "shank cuff"]
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
        .collect();
    vec![
        w.panel(
            "torque on the limb (N m, flexion +)",
            torques,
            Vec::new(),
            None,
        ),
        w.panel(
            "cuff force on the limb (N, forward +)",
            cuffs,
            Vec::new(),
            None,
        ),
        w.panel(
            "pressure (bar)",
            muscle_lines(tr, &tr.pressure_bar, first),
            vec![
                (tr.pressure_max_bar, "valve limit".into()),
                (0.0, "vented".into()),
            ],
            None,
        ),
        w.panel(
            "force (N)",
            muscle_lines(tr, &tr.force_n, first),
            vec![(tr.rated_force_n, "rated force".into())],
            None,
        ),
    ]
}

/// On a treadmill: each foot's (and the virtual other leg's) vertical ground reaction and
/// the pelvis's height; nothing in the air.
fn ground_panels<'a>(w: &Window<'a>) -> Vec<LinePanel<'a>> {
    let (tr, first) = (w.tr, w.first);
    let Some(g) = &tr.ground else {
        return Vec::new();
    };
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
    let pelvis = vec![("pelvis".into(), tail(&g.pelvis_m, first), colour(2), false)];
    vec![
        w.panel(
            "vertical ground reaction (N)",
            lines,
            vec![(g.unsupported_n, "(1 - bws) m g".into())],
            None,
        ),
        w.panel("pelvis height (m)", pelvis, Vec::new(), None),
    ]
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

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn regression_the_patients_and_the_devices_torques_are_told_apart() {
        // leg.png drew the patient's and the device's hip torque in one colour (and the
        // knee's), the legend showing both as the same line.
        let tr = LegTrace {
            t_s: vec![0.0, 0.01],
            patient_nm: [vec![1.0, 2.0], vec![3.0, 4.0]],
            interaction_nm: [vec![5.0, 6.0], vec![7.0, 8.0]],
            ..LegTrace::default()
        };
        let w = Window {
            tr: &tr,
            first: 0,
            event: None,
        };
        let panels = limb_panels(&w);
        let torques = &panels[0].lines;
        assert_eq!(
            torques.len(),
            4,
            "{:?}",
            torques.iter().map(|l| &l.0).collect::<Vec<_>>()
        );
        for (i, a) in torques.iter().enumerate() {
            for b in &torques[i + 1..] {
                assert_ne!(a.2, b.2, "{} and {} share a colour", a.0, b.0);
            }
        }
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
}
