//! The closed-loop gait simulation.
use crate::config::{LoadedScenario, MuscleGeometry, Scenario};
use crate::error::LegError;
use crate::leg::{Leg, JOINT_NAMES};
use pma_control::{AprcNdo, CommandLimits, Controller, Measurement, NominalModel, RefSample};
use pma_model::{DampingMode, MuscleParams, PositionSensor, Valve};
use pma_sim::gait::{GaitReference, GaitSample, JointSample};
use std::time::Instant;

/// A muscle on the leg: geometry, the true three-element model and its valve.
#[derive(Debug, Clone)]
pub struct MuscleActuator {
    /// Geometry.
    pub geometry: MuscleGeometry,
    /// Joint index (0 hip, 1 knee).
    pub joint: usize,
    /// True muscle.
    pub params: MuscleParams,
    valve: Valve,
}

impl MuscleActuator {
    /// Contraction (m) at joint angles `q`.
    pub fn contraction(&self, q: [f64; 2]) -> f64 {
        self.geometry.contraction(q[self.joint])
    }

    /// Contraction rate (m/s).
    pub fn contraction_rate(&self, qd: [f64; 2]) -> f64 {
        self.geometry.side.sign() * self.geometry.pulley_radius_m * qd[self.joint]
    }

    /// Eq. (1) force without the slack clamp (N): negative means slack.
    pub fn force_unclamped(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.params.force_unclamped(
            self.valve.pressure(),
            self.contraction(q),
            self.contraction_rate(qd),
            self.valve.mode(),
        )
    }

    /// Pulling force (N).
    pub fn force(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.force_unclamped(q, qd).max(0.0)
    }

    /// Joint torque (N m, flexion positive).
    pub fn torque(&self, q: [f64; 2], qd: [f64; 2]) -> f64 {
        self.geometry.side.sign() * self.geometry.pulley_radius_m * self.force(q, qd)
    }

    /// Muscle pressure (Pa).
    pub fn pressure(&self) -> f64 {
        self.valve.pressure()
    }
}

/// Co-contraction regulation of one joint.
///
/// Length control of both muscles fixes the joint angle, not the sum of their pressures;
/// with each muscle's observer treating its antagonist as a disturbance, the common mode
/// integrates any inconsistency between the two length references. The regulator uses
/// exactly that: it offsets both references by `delta / 2` (an interference the geometry
/// cannot satisfy), proportional to the error of the filtered common-mode pressure, so
/// the common mode follows its target instead of drifting.
#[derive(Debug, Clone, Copy)]
struct CoContraction {
    target_pa: f64,
    gain_m_per_pa: f64,
    max_m: f64,
    filter_s: f64,
    filtered_pa: f64,
}

impl CoContraction {
    fn update(&mut self, common_mode_pa: f64, dt: f64) -> f64 {
        let a = 1.0 - (-dt / self.filter_s).exp();
        self.filtered_pa += a * (common_mode_pa - self.filtered_pa);
        (self.gain_m_per_pa * (self.target_pa - self.filtered_pa)).clamp(-self.max_m, self.max_m)
    }
}

/// Called after every period of [`LegSim::run`] with the simulation and its sample.
pub type Observer<'a> = &'a mut dyn FnMut(&LegSim, &LegSample);

/// One logged period of the leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegSample {
    /// Time (s).
    pub t_s: f64,
    /// Reference joint angles (rad).
    pub reference_rad: [f64; 2],
    /// Joint angles (rad).
    pub angle_rad: [f64; 2],
    /// Pressure commands (Pa), muscle order of the geometry file.
    pub pressure_cmd_pa: [f64; 4],
    /// Pressures (Pa).
    pub pressure_pa: [f64; 4],
    /// Length references (m).
    pub length_ref_m: [f64; 4],
    /// Contractions (m).
    pub length_m: [f64; 4],
    /// Forces (N).
    pub force_n: [f64; 4],
    /// Controller states.
    pub diagnostics: [pma_control::Diagnostics; 4],
}

/// Per-joint tracking figures (deg).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct JointStats {
    /// RMS tracking error after the first stride (deg).
    pub rms_deg: f64,
    /// Largest tracking error after the first stride (deg).
    pub max_deg: f64,
}

/// Per-muscle figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MuscleStats {
    /// Lowest pressure (Pa).
    pub p_min_pa: f64,
    /// Highest pressure (Pa).
    pub p_max_pa: f64,
    /// Time spent slack (s).
    pub slack_s: f64,
}

/// Mean common-mode pressure over the second stride and the last one (Pa).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CoContractionStats {
    /// Second stride.
    pub start: f64,
    /// Last stride.
    pub end: f64,
}

/// Outcome of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LegReport {
    /// Scenario name.
    pub scenario: String,
    /// Simulated time (s).
    pub duration_s: f64,
    /// `hip`, `knee`.
    pub joints: std::collections::BTreeMap<String, JointStats>,
    /// Per muscle.
    pub muscles: std::collections::BTreeMap<String, MuscleStats>,
    /// Common mode.
    pub cocontraction_pa: CoContractionStats,
    /// Mean total variation of the four pressure commands per second (bar/s): valve
    /// activity, where chattering shows.
    pub command_variation_bar_per_s: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
}

#[derive(Debug, Clone, Default)]
struct Accumulators {
    n: [usize; 2],
    sum_sq: [f64; 2],
    max_abs: [f64; 2],
    p_min: [f64; 4],
    p_max: [f64; 4],
    slack_s: [f64; 4],
    cm_start: (f64, usize),
    /// Common-mode pressure of the last stride's periods (ring buffer, sized once).
    cm_ring: Vec<f64>,
    cm_next: usize,
    cm_filled: bool,
    variation: f64,
    finite: bool,
}

/// The leg with its muscles, controllers and references.
pub struct LegSim {
    scenario: Scenario,
    leg: Leg,
    muscles: Vec<MuscleActuator>,
    controllers: Vec<AprcNdo>,
    encoders: [PositionSensor; 2],
    cocontraction: [CoContraction; 2],
    gait: GaitReference,
    hold: Option<[f64; 2]>,
    t: f64,
    commands: [f64; 4],
    acc: Accumulators,
}

fn joint_ref(j: &JointSample, sign_r: f64, x0: f64, delta: f64) -> RefSample {
    RefSample {
        position_m: x0 + sign_r * j.angle_rad + 0.5 * delta,
        velocity_m_s: sign_r * j.velocity_rad_s,
        acceleration_m_s2: sign_r * j.acceleration_rad_s2,
    }
}

fn pick(g: &GaitSample, joint: usize) -> &JointSample {
    if joint == 0 {
        &g.hip
    } else {
        &g.knee
    }
}

/// Pressures `(flexor, extensor)` with equal forces at the given contractions and mean
/// `p_mean`: the pair holds a joint without gravity torque at that co-contraction.
pub fn balanced_pressures(
    f: &MuscleParams,
    x_f: f64,
    e: &MuscleParams,
    x_e: f64,
    p_mean: f64,
) -> (f64, f64) {
    // F(p, x) = (f0 - k0 x) + (f1 - k1 x) p for each muscle; solve F_f = F_e, p_f + p_e = 2 p_mean.
    let (af, bf) = (
        f.f0_n - f.k0_n_per_m * x_f,
        f.f1_n_per_pa - f.k1_n_per_m_pa * x_f,
    );
    let (ae, be) = (
        e.f0_n - e.k0_n_per_m * x_e,
        e.f1_n_per_pa - e.k1_n_per_m_pa * x_e,
    );
    let p_f = (ae - af + 2.0 * be * p_mean) / (bf + be);
    (p_f, 2.0 * p_mean - p_f)
}

impl LegSim {
    /// Builds the simulation of a loaded scenario, the leg standing still at rest.
    pub fn new(loaded: &LoadedScenario) -> Result<Self, LegError> {
        let sc = loaded.scenario.clone();
        sc.validate()?;
        let leg = Leg::from_urdf_str(
            &loaded.urdf_text,
            &loaded.urdf_source,
            [sc.joints.hip, sc.joints.knee],
            sc.period_s,
            sc.physics_substeps,
        )?;
        let muscles = build_muscles(&sc, &loaded.muscles)?;
        let gait =
            GaitReference::normative(sc.gait.speed, sc.gait.stride_period_s, sc.gait.ramp_s)?;
        let limits = CommandLimits {
            min_pa: 0.0,
            max_pa: sc.plant.valve.pressure_max_pa,
        };
        // Nominal model of each muscle: Table I, a fraction of the standing leg's joint
        // inertia seen through the pulley (see `ControlSettings::nominal_inertia_fraction`),
        // and the antagonist's pull at the co-contraction target as its static load.
        let inertia = leg.inertia();
        let joint_inertia = [inertia.hip_inertia(), inertia.knee_inertia()];
        let mut controllers = Vec::with_capacity(4);
        for m in &muscles {
            let r = m.geometry.pulley_radius_m;
            let antagonist = muscles
                .iter()
                .find(|o| o.joint == m.joint && o.geometry.side != m.geometry.side)
                .ok_or_else(|| LegError::Muscle {
                    muscle: m.geometry.name.clone(),
                    message: "has no antagonist on its joint".into(),
                })?;
            let load = MuscleParams::TABLE_I.force(
                sc.control.cocontraction_pa,
                antagonist.geometry.contraction_at_zero_m,
                0.0,
                DampingMode::Inflation,
            );
            let model = NominalModel {
                mass_kg: sc.control.nominal_inertia_fraction * joint_inertia[m.joint] / (r * r),
                load_force_n: load,
                valve_time_constant_s: sc.control.nominal_valve_time_constant_s,
                ..NominalModel::paper()
            };
            controllers.push(AprcNdo::new(sc.control.gains, model, limits, true));
        }
        let encoders = [
            PositionSensor::new(sc.plant.encoder.sensor(0))?,
            PositionSensor::new(sc.plant.encoder.sensor(1))?,
        ];
        let cc = CoContraction {
            target_pa: sc.control.cocontraction_pa,
            gain_m_per_pa: sc.control.cocontraction_gain_m_per_pa,
            max_m: sc.control.cocontraction_max_m,
            filter_s: sc.control.cocontraction_filter_s,
            filtered_pa: sc.control.cocontraction_pa,
        };
        let cm_ring = vec![0.0; (sc.gait.stride_period_s / sc.period_s).round().max(1.0) as usize];
        let mut sim = Self {
            scenario: sc,
            leg,
            muscles,
            controllers,
            encoders,
            cocontraction: [cc, cc],
            gait,
            hold: None,
            t: 0.0,
            commands: [0.0; 4],
            acc: Accumulators {
                p_min: [f64::INFINITY; 4],
                p_max: [f64::NEG_INFINITY; 4],
                cm_ring,
                finite: true,
                ..Default::default()
            },
        };
        sim.reset_at_rest()?;
        Ok(sim)
    }

    /// Standing at rest: every joint at 0, each pair at the balanced pressures of the
    /// co-contraction target, controllers started on the first reference sample.
    fn reset_at_rest(&mut self) -> Result<(), LegError> {
        self.leg.set_state([0.0, 0.0], [0.0, 0.0]);
        let p_cc = self.scenario.control.cocontraction_pa;
        for j in 0..2 {
            let idx: Vec<usize> = (0..self.muscles.len())
                .filter(|&i| self.muscles[i].joint == j)
                .collect();
            let (fi, ei) = if self.muscles[idx[0]].geometry.side == crate::Side::Flexor {
                (idx[0], idx[1])
            } else {
                (idx[1], idx[0])
            };
            let (f, e) = (&self.muscles[fi], &self.muscles[ei]);
            let (pf, pe) = balanced_pressures(
                &f.params,
                f.geometry.contraction_at_zero_m,
                &e.params,
                e.geometry.contraction_at_zero_m,
                p_cc,
            );
            let valve = self.scenario.plant.valve;
            self.muscles[fi].valve = Valve::new(valve, pf)?;
            self.muscles[ei].valve = Valve::new(valve, pe)?;
        }
        let g = self.gait.sample(0.0);
        for (i, m) in self.muscles.iter().enumerate() {
            let sr = m.geometry.side.sign() * m.geometry.pulley_radius_m;
            let r = joint_ref(pick(&g, m.joint), sr, m.geometry.contraction_at_zero_m, 0.0);
            self.controllers[i].reset(
                Measurement {
                    position_m: m.geometry.contraction_at_zero_m,
                },
                r,
            );
            self.commands[i] = m.pressure();
        }
        Ok(())
    }

    /// Replaces the gait by a constant pose (rad): the reference for a static hold.
    pub fn hold_pose(&mut self, angles: [f64; 2]) {
        self.hold = Some(angles);
    }

    /// Puts the leg at `angles` with `velocities` (the muscles' valves keep their pressure).
    pub fn set_state(&mut self, angles: [f64; 2], velocities: [f64; 2]) {
        self.leg.set_state(angles, velocities);
    }

    fn reference(&self, t: f64) -> GaitSample {
        match self.hold {
            Some(q) => GaitSample {
                hip: JointSample {
                    angle_rad: q[0],
                    ..JointSample::default()
                },
                knee: JointSample {
                    angle_rad: q[1],
                    ..JointSample::default()
                },
            },
            None => self.gait.sample(t),
        }
    }

    /// One period with the valves commanded directly (no controllers): open-loop checks.
    pub fn step_with_commands(&mut self, commands: [f64; 4]) -> LegSample {
        for (m, u) in self.muscles.iter_mut().zip(commands) {
            m.valve.command(u);
        }
        let previous = self.commands;
        self.commands = commands;
        self.advance(previous, [0.0; 4], [pma_control::Diagnostics::NONE; 4])
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The leg (poses, angles).
    pub fn leg(&self) -> &Leg {
        &self.leg
    }

    /// Each muscle as a segment from its anchor to its joint's pulley, in world
    /// coordinates (m), for drawing.
    pub fn muscle_segments(&self) -> [([f64; 3], [f64; 3]); 4] {
        std::array::from_fn(|i| {
            let Some(m) = self.muscles.get(i) else {
                return ([f64::NAN; 3], [f64::NAN; 3]);
            };
            let g = &m.geometry;
            let anchor = self.leg.point_in_world(&g.body_link, g.anchor_m);
            // The pulley sits on the joint axis: the origin of the joint's child link.
            let child = if m.joint == 0 { "thigh" } else { "shank" };
            let pulley = self.leg.point_in_world(child, [0.0, g.anchor_m[1], 0.0]);
            (
                anchor.unwrap_or([f64::NAN; 3]),
                pulley.unwrap_or([f64::NAN; 3]),
            )
        })
    }

    /// The muscles.
    pub fn muscles(&self) -> &[MuscleActuator] {
        &self.muscles
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// One control period: read the encoders, update the regulators and the four
    /// controllers, command the valves, advance the physics. Returns the period's sample.
    pub fn step(&mut self) -> LegSample {
        let dt = self.scenario.period_s;
        let q = self.leg.angles();
        let q_meas = [
            self.encoders[0].measure(q[0]),
            self.encoders[1].measure(q[1]),
        ];
        let g = self.reference(self.t);
        let mut delta = [0.0; 2];
        for (j, d) in delta.iter_mut().enumerate() {
            let (mut sum, mut n) = (0.0, 0);
            for (i, m) in self.muscles.iter().enumerate() {
                if m.joint == j {
                    sum += self.commands[i];
                    n += 1;
                }
            }
            *d = self.cocontraction[j].update(sum / f64::from(n.max(1)), dt);
        }
        let previous = self.commands;
        let mut diagnostics = [pma_control::Diagnostics::NONE; 4];
        let mut length_ref = [0.0; 4];
        for (i, m) in self.muscles.iter_mut().enumerate() {
            let sr = m.geometry.side.sign() * m.geometry.pulley_radius_m;
            let r = joint_ref(
                pick(&g, m.joint),
                sr,
                m.geometry.contraction_at_zero_m,
                delta[m.joint],
            );
            let meas = Measurement {
                position_m: m.geometry.contraction(q_meas[m.joint]),
            };
            let out = self.controllers[i].update(&r, &meas, dt);
            self.commands[i] = out.pressure_cmd_pa;
            diagnostics[i] = out.diagnostics;
            length_ref[i] = r.position_m;
            m.valve.command(out.pressure_cmd_pa);
        }
        self.advance(previous, length_ref, diagnostics)
    }

    /// Physics over one period with the valves as commanded, then the period's sample.
    fn advance(
        &mut self,
        previous: [f64; 4],
        length_ref: [f64; 4],
        diagnostics: [pma_control::Diagnostics; 4],
    ) -> LegSample {
        let dt = self.scenario.period_s;
        let muscles = &mut self.muscles;
        let h = dt / f64::from(self.scenario.physics_substeps);
        let mut slack = [0.0; 4];
        self.leg.step(|leg, _| {
            let (q, qd) = (leg.angles(), leg.velocities());
            let mut tau = [0.0; 2];
            for (i, m) in muscles.iter_mut().enumerate() {
                m.valve.advance(h);
                if m.force_unclamped(q, qd) <= 0.0 {
                    slack[i] += h;
                }
                tau[m.joint] += m.torque(q, qd);
            }
            tau
        });
        self.t += dt;
        let (q, qd) = (self.leg.angles(), self.leg.velocities());
        let g = self.reference(self.t);
        let sample = LegSample {
            t_s: self.t,
            reference_rad: [g.hip.angle_rad, g.knee.angle_rad],
            angle_rad: q,
            pressure_cmd_pa: self.commands,
            pressure_pa: std::array::from_fn(|i| self.muscles[i].pressure()),
            length_ref_m: length_ref,
            length_m: std::array::from_fn(|i| self.muscles[i].contraction(q)),
            force_n: std::array::from_fn(|i| self.muscles[i].force(q, qd)),
            diagnostics,
        };
        self.accumulate(&sample, slack, previous);
        sample
    }

    fn accumulate(&mut self, s: &LegSample, slack: [f64; 4], previous: [f64; 4]) {
        let stride = self.scenario.gait.stride_period_s;
        let a = &mut self.acc;
        a.variation += s
            .pressure_cmd_pa
            .iter()
            .zip(previous)
            .map(|(u, p)| (u - p).abs())
            .sum::<f64>()
            / 4.0;
        a.finite &= s
            .angle_rad
            .iter()
            .chain(&s.pressure_cmd_pa)
            .all(|v| v.is_finite());
        if s.t_s > stride {
            for j in 0..2 {
                let e = (s.reference_rad[j] - s.angle_rad[j]).to_degrees();
                a.n[j] += 1;
                a.sum_sq[j] += e * e;
                a.max_abs[j] = a.max_abs[j].max(e.abs());
            }
        }
        for (i, (p, sl)) in s.pressure_pa.iter().zip(slack).enumerate() {
            a.p_min[i] = a.p_min[i].min(*p);
            a.p_max[i] = a.p_max[i].max(*p);
            a.slack_s[i] += sl;
        }
        let cm = s.pressure_pa.iter().sum::<f64>() / 4.0;
        if s.t_s > stride && s.t_s <= 2.0 * stride {
            a.cm_start.0 += cm;
            a.cm_start.1 += 1;
        }
        if !a.cm_ring.is_empty() {
            a.cm_ring[a.cm_next] = cm;
            a.cm_next = (a.cm_next + 1) % a.cm_ring.len();
            a.cm_filled |= a.cm_next == 0;
        }
    }

    /// Runs for `duration_s`, calling `observe` every period; `progress` gets the fraction
    /// done every 1 % of the run.
    pub fn run(
        &mut self,
        duration_s: f64,
        mut observe: Option<Observer>,
        mut progress: Option<&mut dyn FnMut(f64)>,
    ) -> Result<LegReport, LegError> {
        crate::error::finite_positive("duration_s", duration_s)?;
        let steps = (duration_s / self.scenario.period_s).round() as usize;
        let start = Instant::now();
        let every = (steps / 100).max(1);
        for k in 0..steps {
            let s = self.step();
            if let Some(f) = observe.as_mut() {
                f(self, &s);
            }
            if k.is_multiple_of(every) {
                if let Some(p) = progress.as_mut() {
                    p(k as f64 / steps as f64);
                }
            }
        }
        let wall = start.elapsed().as_secs_f64();
        Ok(self.report(duration_s, wall))
    }

    fn report(&self, duration_s: f64, wall_s: f64) -> LegReport {
        let a = &self.acc;
        let joints = JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(j, n)| {
                let rms = if a.n[j] > 0 {
                    (a.sum_sq[j] / a.n[j] as f64).sqrt()
                } else {
                    f64::NAN
                };
                (
                    (*n).to_owned(),
                    JointStats {
                        rms_deg: rms,
                        max_deg: if a.n[j] > 0 { a.max_abs[j] } else { f64::NAN },
                    },
                )
            })
            .collect();
        let muscles = self
            .muscles
            .iter()
            .enumerate()
            .map(|(i, m)| {
                (
                    m.geometry.name.clone(),
                    MuscleStats {
                        p_min_pa: a.p_min[i],
                        p_max_pa: a.p_max[i],
                        slack_s: a.slack_s[i],
                    },
                )
            })
            .collect();
        let last = if a.cm_filled {
            &a.cm_ring[..]
        } else {
            &a.cm_ring[..a.cm_next]
        };
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        LegReport {
            scenario: self.scenario.name.clone(),
            duration_s,
            joints,
            muscles,
            cocontraction_pa: CoContractionStats {
                start: if a.cm_start.1 > 0 {
                    a.cm_start.0 / a.cm_start.1 as f64
                } else {
                    f64::NAN
                },
                end: mean(last),
            },
            command_variation_bar_per_s: a.variation / self.t.max(1e-12) / 1e5,
            finite: a.finite,
            real_time_factor: duration_s / wall_s.max(1e-12),
        }
    }
}

fn build_muscles(
    sc: &Scenario,
    geometry: &[MuscleGeometry],
) -> Result<Vec<MuscleActuator>, LegError> {
    if geometry.len() != 4 {
        return Err(LegError::Invalid {
            name: "number of muscles".into(),
            value: geometry.len() as f64,
            expected: "must be 4: a flexor and an extensor on hip and knee",
        });
    }
    let links: [(&str, [&str; 2]); 2] =
        [("hip", ["pelvis", "thigh"]), ("knee", ["thigh", "shank"])];
    let mut out = Vec::with_capacity(4);
    for g in geometry {
        let err = |message: String| LegError::Muscle {
            muscle: g.name.clone(),
            message,
        };
        let joint = JOINT_NAMES
            .iter()
            .position(|n| *n == g.joint)
            .ok_or_else(|| {
                err(format!(
                    "unknown joint `{}` (the leg has hip and knee)",
                    g.joint
                ))
            })?;
        if !links[joint].1.contains(&g.body_link.as_str()) {
            return Err(err(format!(
                "unknown link `{}` for joint `{}` (expected `{}` or `{}`)",
                g.body_link, g.joint, links[joint].1[0], links[joint].1[1]
            )));
        }
        let scale = sc
            .plant
            .muscle_scale
            .get(&g.name)
            .copied()
            .unwrap_or_default();
        let params = scale.apply(MuscleParams::TABLE_I);
        params.validate()?;
        out.push(MuscleActuator {
            geometry: g.clone(),
            joint,
            params,
            valve: Valve::new(sc.plant.valve, 0.0)?,
        });
    }
    for name in sc.plant.muscle_scale.keys() {
        if !geometry.iter().any(|g| &g.name == name) {
            return Err(LegError::Muscle {
                muscle: name.clone(),
                message: "plant.muscle_scale names a muscle the geometry does not have".into(),
            });
        }
    }
    for (j, joint_name) in JOINT_NAMES.iter().enumerate() {
        let sides: Vec<_> = out
            .iter()
            .filter(|m| m.joint == j)
            .map(|m| m.geometry.side)
            .collect();
        if sides.len() != 2 || sides[0] == sides[1] {
            return Err(LegError::Invalid {
                name: format!("muscles on {joint_name}"),
                value: sides.len() as f64,
                expected: "each joint needs exactly one flexor and one extensor",
            });
        }
    }
    Ok(out)
}
