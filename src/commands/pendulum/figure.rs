use crate::plot::DrawResult;
use crate::plot::*;
use plotters::prelude::*;
use std::path::Path;

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
