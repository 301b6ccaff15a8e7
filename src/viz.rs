//! Glue between the runs and `pma-viz`: the layout (entity paths, legends, colours) of the
//! bench, the leg and the rig, the mapping of their periods onto frames, and one
//! [`Recorder`] for each (a viewer's error is kept and reported after the run).
use anyhow::Result;
use pma_bench::{MuscleBench, Sample};
use pma_control::MuscleStep;
use pma_leg::patient::SpasmEvent;
use pma_leg::{LegOutput, LegPlant, LegSample, LegSim, VisualShape};
use pma_loop::{Period, Recorder, Start};
use pma_viz::{Frame, Marker, Shape, Sink, Viz, VizError};

/// Per-muscle series, in this order, under `muscles/<name>/`.
pub const MUSCLE_SERIES: [(&str, &str); 10] = [
    ("pressure_cmd_pa", "pressure command (Pa)"),
    ("pressure_pa", "pressure (Pa)"),
    ("length_ref_m", "contraction reference (m)"),
    ("length_m", "contraction (m)"),
    ("proxy_m", "proxy position (m)"),
    ("s_p", "S_p (m/s)"),
    ("s_q", "S_q (m/s)"),
    ("gain_hat", "adaptive gain"),
    ("disturbance_hat", "disturbance estimate (m/s^2)"),
    ("force_n", "force (N)"),
];

/// Per-joint series under `joints/<name>/`.
pub const JOINT_SERIES: [(&str, &str); 5] = [
    ("reference_deg", "reference (deg)"),
    ("angle_deg", "angle (deg)"),
    ("error_deg", "error (deg)"),
    ("patient_torque_nm", "patient torque (N m, flexion +)"),
    ("spasm_torque_nm", "spasm torque (N m, flexion +)"),
];

/// The text log of the leg's events (spasm onsets and ends).
pub const EVENTS_PATH: &str = "events";

/// The joints' names and the links they move, in the leg's joint order.
const JOINT_LINKS: [(&str, &str); 2] = [("hip", "thigh"), ("knee", "shank")];

const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

fn muscle_series(viz: &mut Viz, name: &str) -> Result<()> {
    for (k, (leaf, legend)) in MUSCLE_SERIES.iter().enumerate() {
        viz.series(
            &format!("muscles/{name}/{leaf}"),
            &format!("{name} {legend}"),
            PALETTE[k],
        )?;
    }
    Ok(())
}

/// Opens the sink for a run with period `period_s` (`None` when off).
pub fn open(
    sink: &Sink,
    app: &'static str,
    period_s: f64,
    rate_hz: Option<f64>,
) -> Result<Option<Viz>> {
    Ok(Viz::open(sink, app, period_s, rate_hz)?)
}

/// Ends a run's recording. A viewer too slow to take the end of it is a warning, not a
/// failure: the run and its metrics are complete.
pub fn finish(viz: Option<Viz>) -> Result<()> {
    match viz.map(Viz::finish) {
        Some(Err(e @ pma_viz::VizError::FlushTimeout { .. })) => {
            eprintln!("warning: {e}");
            Ok(())
        }
        Some(Err(e)) => Err(e.into()),
        _ => Ok(()),
    }
}

/// The bench's layout: one muscle, its series and the reference.
pub fn bench_layout(viz: &mut Viz, meta: &str) -> Result<()> {
    viz.document("metadata", meta)?;
    muscle_series(viz, "muscle")?;
    viz.series("reference/x_d_m", "reference x_d (m)", [0, 0, 0])?;
    Ok(())
}

/// A bench sample as a frame's scalars (order of [`bench_layout`]).
pub fn bench_scalars(s: &Sample, out: &mut [f64; 11]) {
    let d = &s.diagnostics;
    *out = [
        s.pressure_cmd_pa,
        s.pressure_pa,
        s.reference_m,
        s.position_m,
        d.proxy_position_m,
        d.s_p,
        d.s_q,
        d.gain_hat,
        d.disturbance_hat,
        s.force_n,
        s.reference_m,
    ];
}

fn shape(v: &VisualShape) -> Shape {
    let f = |a: [f64; 3]| [a[0] as f32, a[1] as f32, a[2] as f32];
    match *v {
        VisualShape::Cylinder {
            center,
            radius,
            length,
        } => Shape::Cylinder {
            center: f(center),
            radius: radius as f32,
            length: length as f32,
        },
        VisualShape::Box { center, size } => Shape::Box {
            center: f(center),
            half_size: f(size.map(|x| 0.5 * x)),
        },
    }
}

/// The leg's layout: links with their URDF shapes, muscles, joint and muscle series.
pub fn leg_layout(viz: &mut Viz, sim: &LegSim, meta: &str) -> Result<()> {
    viz.document("metadata", meta)?;
    let leg = sim.leg();
    let names: Vec<String> = leg.link_names().map(str::to_owned).collect();
    for (i, n) in names.iter().enumerate() {
        let shapes: Vec<Shape> = leg.visuals(i).iter().map(shape).collect();
        viz.link(
            n,
            &shapes,
            if n == "pelvis" {
                [150, 150, 165]
            } else {
                [217, 178, 140]
            },
        )?;
    }
    let p_max = sim.scenario().plant.valve.pressure_max_pa;
    for m in sim.muscles() {
        viz.muscle(&m.geometry.name, p_max)?;
    }
    for (j, _) in JOINT_LINKS {
        for (k, (leaf, legend)) in JOINT_SERIES.iter().enumerate() {
            viz.series(
                &format!("joints/{j}/{leaf}"),
                &format!("{j} {legend}"),
                PALETTE[k],
            )?;
        }
    }
    for m in sim.muscles() {
        muscle_series(viz, &m.geometry.name)?;
    }
    Ok(())
}

/// Number of scalars of the leg layout.
pub const LEG_SCALARS: usize = 2 * JOINT_SERIES.len() + 4 * MUSCLE_SERIES.len();

/// A leg sample as the leg layout's scalars.
pub fn leg_scalars(s: &LegSample, out: &mut [f64; LEG_SCALARS]) {
    let mut k = 0;
    for j in 0..2 {
        let (r, a) = (s.reference_rad[j].to_degrees(), s.angle_rad[j].to_degrees());
        for v in [r, a, r - a, s.patient_nm[j], s.spasm_nm[j]] {
            out[k] = v;
            k += 1;
        }
    }
    for i in 0..4 {
        let d = &s.diagnostics[i];
        for v in [
            s.pressure_cmd_pa[i],
            s.pressure_pa[i],
            s.length_ref_m[i],
            s.length_m[i],
            d.proxy_position_m,
            d.s_p,
            d.s_q,
            d.gain_hat,
            d.disturbance_hat,
            s.force_n[i],
        ] {
            out[k] = v;
            k += 1;
        }
    }
}

/// Logs one leg period (layout of [`leg_layout`]).
pub fn push_leg(
    viz: &mut Viz,
    plant: &LegPlant,
    s: &LegSample,
    step: i64,
    scalars: &mut [f64; LEG_SCALARS],
) -> Result<()> {
    if step % viz.decimation() != 0 {
        return Ok(());
    }
    leg_scalars(s, scalars);
    let poses = [
        plant.leg().link_pose(0),
        plant.leg().link_pose(1),
        plant.leg().link_pose(2),
    ];
    let seg = plant.muscle_segments();
    let lines: [([f64; 3], [f64; 3], f64); 4] =
        std::array::from_fn(|i| (seg[i].0, seg[i].1, s.pressure_pa[i]));
    viz.push(&Frame {
        t_s: s.t_s,
        step,
        scalars: scalars.as_slice(),
        link_poses: &poses,
        muscle_lines: &lines,
    })?;
    Ok(())
}

/// Streams a run to Rerun as a [`Recorder`]; the first error is kept for [`Self::finish`].
pub struct VizRecorder {
    viz: Viz,
    step: i64,
    error: Option<VizError>,
    /// Time of the previous leg period (s): spasm onsets and ends are logged when crossed.
    previous_t_s: f64,
}

impl VizRecorder {
    /// Records into `viz`, whose layout is already registered.
    pub fn new(viz: Viz) -> Self {
        Self {
            viz,
            step: 0,
            error: None,
            previous_t_s: f64::NEG_INFINITY,
        }
    }

    fn keep(&mut self, r: Result<()>) {
        if let Err(e) = r {
            if self.error.is_none() {
                self.error = Some(VizError::Rerun(e.to_string()));
            }
        }
    }

    fn push_bench(&mut self, s: &Sample) {
        let r = push_bench(&mut self.viz, s, self.step);
        self.keep(r);
    }

    /// Ends the recording: the first error of the run, or the viewer's.
    pub fn finish(self) -> Result<()> {
        if let Some(e) = self.error {
            return Err(e.into());
        }
        finish(Some(self.viz))
    }
}

/// Logs one bench period (layout of [`bench_layout`]), if `step` is not decimated away.
pub fn push_bench(viz: &mut Viz, s: &Sample, step: i64) -> Result<()> {
    if step % viz.decimation() != 0 {
        return Ok(());
    }
    let mut scalars = [0.0; 11];
    bench_scalars(s, &mut scalars);
    viz.push(&Frame {
        t_s: s.t_s,
        step,
        scalars: &scalars,
        link_poses: &[],
        muscle_lines: &[],
    })?;
    Ok(())
}

impl Recorder<MuscleBench, MuscleStep> for VizRecorder {
    fn record(&mut self, p: &Period<'_, MuscleBench, MuscleStep>) {
        self.step += 1;
        self.push_bench(&Sample::of(p));
    }
}

impl Recorder<pma_rig::Rig, MuscleStep> for VizRecorder {
    fn record(&mut self, p: &Period<'_, pma_rig::Rig, MuscleStep>) {
        self.step += 1;
        let sample = Sample {
            t_s: p.t_s,
            reference_m: p.output.reference.position_m,
            position_m: p.reading.position_m,
            measured_m: p.reading.position_m,
            pressure_cmd_pa: *p.written,
            // A rig measures neither the muscle's pressure nor its force.
            pressure_pa: f64::NAN,
            force_n: f64::NAN,
            diagnostics: p.output.control.diagnostics,
        };
        self.push_bench(&sample);
    }
}

impl Recorder<LegPlant, LegOutput> for VizRecorder {
    fn start(&mut self, s: &Start<'_, LegPlant>) {
        self.previous_t_s = s.t_s;
    }

    fn record(&mut self, p: &Period<'_, LegPlant, LegOutput>) {
        self.step += 1;
        let mut scalars = [0.0; LEG_SCALARS];
        let r = push_leg(
            &mut self.viz,
            p.backend,
            &LegSample::of(p),
            self.step,
            &mut scalars,
        );
        self.keep(r);
        if let Some(patient) = p.backend.patient() {
            let r = mark_spasms(
                &self.viz,
                patient.events(),
                (self.previous_t_s, p.t_s),
                self.step,
            );
            self.keep(r);
            self.previous_t_s = p.t_s;
        }
    }
}

/// The entity marking a spasm on `joint`: a child of the link the joint moves, so that it
/// sits on the joint and moves with the leg.
pub fn spasm_marker_path(joint: usize) -> String {
    format!("world/{}/spasm", JOINT_LINKS[joint].1)
}

/// Logs the spasms that start or end by `t_s`: a line in [`EVENTS_PATH`] each time, and a
/// red labelled ball on the joint while a spasm acts on it (kept until the last of
/// overlapping spasms ends).
fn mark_spasms(
    viz: &Viz,
    events: &[SpasmEvent],
    (previous_t_s, t_s): (f64, f64),
    step: i64,
) -> Result<()> {
    // What happened since the previous period: onsets and ends in (previous_t_s, t_s].
    let crossed = |at: f64| previous_t_s < at && at <= t_s;
    for e in events {
        let joint = JOINT_LINKS[e.joint].0;
        if crossed(e.t_s) {
            let text = format!(
                "{joint} spasm: {} {:.1} N m for {:.2} s",
                e.direction, e.amplitude_nm, e.duration_s
            );
            viz.event(t_s, step, EVENTS_PATH, &text, "WARN")?;
            let marker = Marker {
                position_m: [0.0; 3],
                radius_m: 0.045,
                rgb: [230, 30, 30],
                label: text,
            };
            viz.marker(t_s, step, &spasm_marker_path(e.joint), &marker)?;
        }
        if crossed(e.end_s()) {
            viz.event(
                t_s,
                step,
                EVENTS_PATH,
                &format!("{joint} spasm ends"),
                "INFO",
            )?;
            let still_acting = events
                .iter()
                .any(|o| o.joint == e.joint && o.t_s <= t_s && t_s < o.end_s());
            if !still_acting {
                viz.clear(t_s, step, &spasm_marker_path(e.joint))?;
            }
        }
    }
    Ok(())
}
