//! Glue between the runs and `pma-viz`: the layout (entity paths, legends, colours) of the
//! bench, the leg and the rig, the mapping of their periods onto frames, and one
//! [`Recorder`] for each (a viewer's error is kept and reported after the run).
use anyhow::Result;
use pma_bench::{MuscleBench, Sample};
use pma_control::MuscleStep;
use pma_leg::patient::SpasmEvent;
use pma_leg::{LegOutput, LegPlant, LegSim, PerLeg, SupervisedLeg, TrainerSample, VisualShape};
use pma_loop::{Period, Recorder, Signals, Start};
use pma_studies::pendulum::PendulumSample;
use pma_viz::{Frame, Marker, Shape, Sink, Viz, VizError};

/// The text log of the leg's events (spasm onsets and ends).
pub const EVENTS_PATH: &str = "events";

/// The joints' names and the links they move, in the leg's joint order.
const JOINT_LINKS: [(&str, &str); 2] = [("hip", "thigh"), ("knee", "shank")];

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

/// The bench's layout: one muscle's series ([`Sample::schema`]); returns their number.
pub fn bench_layout(viz: &mut Viz, meta: &str) -> Result<usize> {
    viz.document("metadata", meta)?;
    let schema = Sample::schema();
    viz.schema(&schema)?;
    Ok(schema.len())
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

/// The exoskeleton's layout: links with their URDF shapes, muscles, and the series of
/// [`TrainerSample::schema`]; returns their number.
pub fn leg_layout(viz: &mut Viz, sim: &LegSim, meta: &str) -> Result<usize> {
    leg_scene(viz, sim, meta)?;
    let schema = TrainerSample::schema(
        &sim.plant().muscle_names(),
        sim.leg_count(),
        sim.exo().ground().is_some(),
    );
    viz.schema(&schema)?;
    Ok(schema.len())
}

/// The pendulum test's layout: the leg's scene and the series of
/// [`PendulumSample::schema`] (what the test has: no reference, no controller); returns
/// their number.
pub fn pendulum_layout(viz: &mut Viz, sim: &LegSim, meta: &str) -> Result<usize> {
    leg_scene(viz, sim, meta)?;
    let schema = PendulumSample::schema();
    viz.schema(&schema)?;
    Ok(schema.len())
}

/// The recording's description, the links with their URDF shapes and the muscles' lines.
fn leg_scene(viz: &mut Viz, sim: &LegSim, meta: &str) -> Result<()> {
    viz.document("metadata", meta)?;
    let exo = sim.exo();
    let names: Vec<String> = exo.link_names().map(str::to_owned).collect();
    for (i, n) in names.iter().enumerate() {
        let shapes: Vec<Shape> = exo.visuals(i).iter().map(shape).collect();
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
    if exo.ground().is_some() {
        treadmill_scene(viz, sim.leg_count())?;
    }
    let p_max = sim.scenario().plant.valve.pressure_max_pa;
    for m in sim.muscles() {
        viz.muscle(&m.label(sim.leg_count()), p_max)?;
    }
    Ok(())
}

/// Spacing of the belt's stripes (m): they move with the belt.
const STRIPE_SPACING_M: f64 = 0.2;
/// The belt's length and width (m), centred under the hip.
const BELT_SIZE_M: [f64; 2] = [2.0, 0.4];

/// The treadmill: the belt (a slab whose top is the contact plane), its stripes (a link
/// that moves backwards with the belt, by one spacing and back), and each foot's ground
/// reaction (contact points and the force as an arrow at the centre of pressure).
fn treadmill_scene(viz: &mut Viz, legs: usize) -> Result<()> {
    let [length, width] = BELT_SIZE_M.map(|v| v as f32);
    viz.fixture(
        "belt",
        &Shape::Box {
            center: [0.0, 0.0, -0.02],
            half_size: [0.5 * length, 0.5 * width, 0.02],
        },
        [60, 60, 70],
    )?;
    let n = (BELT_SIZE_M[0] / STRIPE_SPACING_M) as i32;
    let stripes: Vec<Shape> = (0..n)
        .map(|k| Shape::Box {
            center: [
                (-0.5 * BELT_SIZE_M[0] + (f64::from(k) + 0.5) * STRIPE_SPACING_M) as f32,
                0.0,
                0.001,
            ],
            half_size: [0.01, 0.5 * width, 0.001],
        })
        .collect();
    viz.link(BELT_STRIPES, &stripes, [200, 200, 90])?;
    for leg in 0..legs {
        viz.ground(&foot_on_belt_path(legs, leg))?;
    }
    Ok(())
}

/// The belt's stripes as a link of the scene.
const BELT_STRIPES: &str = "belt_stripes";

/// Most links a frame carries (the two-leg trainer has eight and the belt's stripes).
const MAX_LINKS: usize = 12;

/// Where foot `leg`'s ground reaction is drawn (`world/<this>/grf`).
pub fn foot_on_belt_path(legs: usize, leg: usize) -> String {
    if legs > 1 {
        format!("{}_foot_on_belt", pma_leg::SIDES[leg])
    } else {
        "foot_on_belt".to_owned()
    }
}

/// Logs one period of the exoskeleton (layout of [`leg_layout`]); `scalars` has the
/// schema's length.
pub fn push_leg(
    viz: &mut Viz,
    plant: &LegPlant,
    s: &TrainerSample,
    step: i64,
    scalars: &mut [f64],
) -> Result<()> {
    if step % viz.decimation() != 0 {
        return Ok(());
    }
    s.values(scalars);
    let pressures = s.legs.map(|l| l.pressure_pa);
    push_leg_frame(viz, plant, (s.t_s, step), &pressures, scalars)
}

/// Most contact spheres drawn per foot.
const MAX_CONTACTS: usize = 4;

/// Logs one frame of the exoskeleton: the links, every leg's muscles' lines coloured by
/// its `pressure_pa`, each foot's ground reaction, and the series' `scalars`.
fn push_leg_frame(
    viz: &mut Viz,
    plant: &LegPlant,
    (t_s, step): (f64, i64),
    pressure_pa: &PerLeg<[f64; 4]>,
    scalars: &[f64],
) -> Result<()> {
    let exo = plant.exo();
    let mut poses = [([0.0; 3], [0.0, 0.0, 0.0, 1.0]); MAX_LINKS];
    let links = exo.link_count().min(MAX_LINKS - 1);
    for (i, pose) in poses.iter_mut().enumerate().take(links) {
        *pose = exo.link_pose(i);
    }
    let mut n = links;
    let legs = exo.leg_count().min(pma_leg::MAX_LEGS);
    let mut contacts = [[[0.0; 3]; MAX_CONTACTS]; pma_leg::MAX_LEGS];
    let mut feet = [(0usize, [f64::NAN; 3], [0.0; 3]); pma_leg::MAX_LEGS];
    let has_ground = if let Some(g) = exo.ground() {
        // The stripes travel backwards with the belt, wrapping every spacing.
        let travelled = g.belt_travel_m();
        poses[n] = (
            [-travelled.rem_euclid(STRIPE_SPACING_M), 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        );
        n += 1;
        for (leg, foot) in feet.iter_mut().enumerate().take(legs) {
            let (mut k, mut force) = (0, [0.0; 3]);
            for c in g.sphere_contacts(leg).iter().flatten() {
                if k < MAX_CONTACTS {
                    contacts[leg][k] = c.point_m;
                    k += 1;
                }
                for (f, v) in force.iter_mut().zip(c.force_n) {
                    *f += v;
                }
            }
            let at = [g.centre_of_pressure_x_m(leg), contacts[leg][0][1], 0.0];
            *foot = (k, at, force);
        }
        true
    } else {
        false
    };
    let grounds: [pma_viz::GroundFrame; pma_leg::MAX_LEGS] =
        std::array::from_fn(|leg| pma_viz::GroundFrame {
            contacts_m: &contacts[leg][..feet[leg].0],
            at_m: feet[leg].1,
            force_n: feet[leg].2,
        });
    let mut lines = [([0.0; 3], [0.0; 3], 0.0); 4 * pma_leg::MAX_LEGS];
    for leg in 0..legs {
        let seg = plant.muscle_segments(leg);
        for i in 0..4 {
            let p = pressure_pa.get(leg).map_or(f64::NAN, |p| p[i]);
            lines[4 * leg + i] = (seg[i].0, seg[i].1, p);
        }
    }
    viz.push(&Frame {
        t_s,
        step,
        scalars,
        link_poses: &poses[..n],
        muscle_lines: &lines[..4 * legs],
        grounds: if has_ground { &grounds[..legs] } else { &[] },
    })?;
    Ok(())
}

/// Streams a run to Rerun as a [`Recorder`]; the first error is kept for [`Self::finish`].
pub struct VizRecorder {
    viz: Viz,
    step: i64,
    /// One frame's scalars, sized once for the layout.
    scalars: Vec<f64>,
    error: Option<VizError>,
    /// Time of the previous leg period (s): spasm onsets and ends are logged when crossed.
    previous_t_s: f64,
    /// Which series a leg run logs.
    leg_series: LegSeries,
    /// The rig's last finite position reading (m): where its end is marked on the position plot.
    last_position_m: f64,
}

/// The series of a leg run.
#[derive(Clone, Copy)]
enum LegSeries {
    /// [`LegSample`]'s: a controlled run.
    Gait,
    /// [`PendulumSample`]'s, with the knee's damping (N m s/rad).
    Pendulum { knee_damping_nm_s_per_rad: f64 },
}

impl VizRecorder {
    /// Records into `viz`, whose layout of `channels` series is already registered.
    pub fn new(viz: Viz, channels: usize) -> Self {
        Self {
            viz,
            step: 0,
            scalars: vec![0.0; channels],
            error: None,
            previous_t_s: f64::NEG_INFINITY,
            leg_series: LegSeries::Gait,
            last_position_m: f64::NAN,
        }
    }

    /// Records a pendulum test into `viz`, whose [`pendulum_layout`] of `channels` series is
    /// registered; `knee_damping_nm_s_per_rad` is the knee's joint damping.
    pub fn pendulum(viz: Viz, channels: usize, knee_damping_nm_s_per_rad: f64) -> Self {
        Self {
            leg_series: LegSeries::Pendulum {
                knee_damping_nm_s_per_rad,
            },
            ..Self::new(viz, channels)
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
        let r = push_bench(&mut self.viz, s, self.step, &mut self.scalars);
        self.keep(r);
    }

    fn push_pendulum(
        &mut self,
        p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>,
        knee_damping_nm_s_per_rad: f64,
    ) -> Result<()> {
        if self.step % self.viz.decimation() != 0 {
            return Ok(());
        }
        PendulumSample::of(p, knee_damping_nm_s_per_rad).values(&mut self.scalars);
        let pressures = p.truth.legs.map(|l| l.pressure_pa);
        push_leg_frame(
            &mut self.viz,
            p.backend,
            (p.t_s, self.step),
            &pressures,
            &self.scalars,
        )
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
pub fn push_bench(viz: &mut Viz, s: &Sample, step: i64, scalars: &mut [f64]) -> Result<()> {
    if step % viz.decimation() != 0 {
        return Ok(());
    }
    s.values(scalars);
    viz.push(&Frame {
        t_s: s.t_s,
        step,
        scalars,
        link_poses: &[],
        muscle_lines: &[],
        grounds: &[],
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
        if p.reading.position_m.is_finite() {
            self.last_position_m = p.reading.position_m;
        }
        let sample = Sample {
            t_s: p.t_s,
            reference_m: p.output.reference.position_m,
            position_m: p.reading.position_m,
            measured_m: p.reading.position_m,
            pressure_cmd_pa: *p.written,
            // The valve's pressure channel if the rig has one (NaN otherwise); a rig does
            // not measure the muscle's force.
            pressure_pa: p.truth.pressure_pa,
            force_n: f64::NAN,
            diagnostics: p.output.control.diagnostics,
        };
        self.push_bench(&sample);
    }

    /// The end of a rig run in the text log: a fault (named, with its message) or an
    /// interruption as an error, and the vent.
    fn end(
        &mut self,
        end: &pma_loop::End<pma_control::supervisor::Fault<pma_rig::DaqError>>,
        t_s: f64,
    ) {
        let (text, level) = match end {
            pma_loop::End::Completed => ("run completed; valve vented".to_owned(), "INFO"),
            pma_loop::End::Stopped => ("interrupted; valve vented".to_owned(), "WARN"),
            pma_loop::End::Fault { error, .. } => (
                format!("fault `{}`: {error}; valve vented", error.name()),
                "ERROR",
            ),
        };
        let marker = match end {
            pma_loop::End::Fault { error, .. } => format!("fault `{}`, vent", error.name()),
            _ => "vent".to_owned(),
        };
        let r = self
            .viz
            .event(t_s, self.step, EVENTS_PATH, &text, level)
            .and_then(|()| {
                self.viz.series_marker(
                    t_s,
                    self.step,
                    RIG_END_MARKER_PATH,
                    &marker,
                    self.last_position_m,
                )
            })
            .map_err(anyhow::Error::from);
        self.keep(r);
    }
}

impl Recorder<SupervisedLeg, PerLeg<LegOutput>> for VizRecorder {
    fn start(&mut self, s: &Start<'_, SupervisedLeg>) {
        self.previous_t_s = s.t_s;
    }

    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        self.step += 1;
        let r = match self.leg_series {
            LegSeries::Gait => push_leg(
                &mut self.viz,
                p.backend,
                &TrainerSample::of(p),
                self.step,
                &mut self.scalars,
            ),
            LegSeries::Pendulum {
                knee_damping_nm_s_per_rad,
            } => self.push_pendulum(p, knee_damping_nm_s_per_rad),
        };
        self.keep(r);
        let legs = p.backend.leg_count();
        for (leg, patient) in p.backend.patients().iter().enumerate() {
            let r = mark_spasms(
                &self.viz,
                (legs, leg),
                patient.events(),
                (self.previous_t_s, p.t_s),
                self.step,
            );
            self.keep(r);
        }
        self.previous_t_s = p.t_s;
    }

    /// A run that ended on a fault says so on the events log; a collapse the trainer
    /// stopped also as a marker on the trainer's pelvis series ([`COLLAPSE_MARKER_PATH`]).
    fn end(&mut self, end: &pma_loop::End<pma_control::Fault<pma_leg::LegError>>, t_s: f64) {
        let pma_loop::End::Fault { error, .. } = end else {
            return;
        };
        let collapse = matches!(
            error,
            pma_control::Fault::Backend(pma_leg::LegError::Collapse { .. })
        );
        let text = if collapse {
            error.to_string().replace("daq-error: ", "")
        } else {
            format!("fault `{}`: {error}; muscles vented", error.name())
        };
        let r = self
            .viz
            .event(t_s, self.step, EVENTS_PATH, &text, "ERROR")
            .and_then(|()| match collapse {
                true => {
                    self.viz
                        .series_marker(t_s, self.step, COLLAPSE_MARKER_PATH, "collapse", 0.0)
                }
                false => Ok(()),
            })
            .map_err(anyhow::Error::from);
        self.keep(r);
    }
}

/// A collapse the trainer stopped, as a cross at its time.
pub const COLLAPSE_MARKER_PATH: &str = "trainer/collapse";

/// The rig's end (fault or vent) as a cross beside the position series, at the last
/// reading.
pub const RIG_END_MARKER_PATH: &str = "muscles/muscle/end";

/// The entity marking a spasm on `joint` of leg `leg` of a trainer of `legs` legs: a child
/// of the link the joint moves, so that it sits on the joint and moves with the leg.
pub fn spasm_marker_path((legs, leg): (usize, usize), joint: usize) -> String {
    let link = JOINT_LINKS[joint].1;
    if legs > 1 {
        format!("world/{}_{link}/spasm", pma_leg::SIDES[leg])
    } else {
        format!("world/{link}/spasm")
    }
}

/// Logs the spasms that start or end by `t_s`: a line in [`EVENTS_PATH`] each time, and a
/// red labelled ball on the joint while a spasm acts on it (kept until the last of
/// overlapping spasms ends).
fn mark_spasms(
    viz: &Viz,
    leg: (usize, usize),
    events: &[SpasmEvent],
    (previous_t_s, t_s): (f64, f64),
    step: i64,
) -> Result<()> {
    // What happened since the previous period: onsets and ends in (previous_t_s, t_s].
    let crossed = |at: f64| previous_t_s < at && at <= t_s;
    for e in events {
        let joint = pma_leg::plant::leg_label(leg.0, leg.1, JOINT_LINKS[e.joint].0);
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
            viz.marker(t_s, step, &spasm_marker_path(leg, e.joint), &marker)?;
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
                viz.clear(t_s, step, &spasm_marker_path(leg, e.joint))?;
            }
        }
    }
    Ok(())
}
