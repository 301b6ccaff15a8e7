use crate::base::{PerLeg, JOINT_NAMES, SIDES};
use crate::control::LegOutput;
use crate::ground::FootReaction;
use crate::patient::PatientTorques;
use crate::plant::{LegState, SupervisedLeg, TrainerState};
use pma_control::Diagnostics;
use pma_loop::{Period, Schema, Signals};

/// What one leg's foot did in one period, on a treadmill.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FootSample {
    /// The belt's reaction on the foot.
    pub reaction: FootReaction,
    /// Whether the reference's foot is in stance.
    pub reference_stance: bool,
    /// The passive ankle's angle (rad, dorsiflexion positive; NaN for a fixed ankle).
    pub ankle_rad: f64,
    /// The orthosis's torque on the ankle (N m, dorsiflexion positive).
    pub ankle_torque_nm: f64,
}

/// One leg's channels of one period: its state at the reading and what its controllers
/// made of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LegSample {
    /// Reference joint angles (rad).
    pub reference_rad: [f64; 2],
    /// Joint angles (rad).
    pub angle_rad: [f64; 2],
    /// Reference joint velocities (rad/s).
    pub reference_velocity_rad_s: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// Pressure commands computed from this reading (Pa), muscle order of the geometry file.
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
    pub diagnostics: [Diagnostics; 4],
    /// The patient's torque at hip and knee (N m, flexion positive), all parts.
    pub patient_nm: [f64; 2],
    /// Its parts (N m): reflex, spasm (non-zero while a spasm acts on the joint), voluntary
    /// effort, passive stiffness.
    pub patient_parts_nm: PatientTorques,
    /// The torque the device puts into the limb (N m, flexion positive).
    pub interaction_nm: [f64; 2],
    /// The thigh and shank cuff forces that put it there (N, forward positive).
    pub cuff_force_n: [f64; 2],
    /// Its foot on the belt, on a treadmill.
    pub foot: Option<FootSample>,
}

/// What the harness, a virtual other leg and the pelvis did in one period, on a treadmill.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroundSample {
    /// The virtual other leg's force on the pelvis (N; 0 without one).
    pub other_leg_n: f64,
    /// The harness's upward force (N).
    pub support_n: f64,
    /// The harness's fore-aft force on the pelvis (N, forward positive).
    pub harness_fore_aft_n: f64,
    /// The pelvis frame `[fore-aft, height above the belt]` (m).
    pub pelvis_m: [f64; 2],
}

/// One period of the exoskeleton as logs show it: every leg's channels, and on a
/// treadmill the harness's and the pelvis's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainerSample {
    /// Time (s).
    pub t_s: f64,
    /// Each leg's channels.
    pub legs: PerLeg<LegSample>,
    /// The harness and the pelvis, on a treadmill.
    pub ground: Option<GroundSample>,
}

impl LegSample {
    /// Leg `leg`'s view of one loop period.
    fn of(state: &TrainerState, leg: usize, output: &LegOutput, written: &[f64; 4]) -> Self {
        let s: &LegState = &state.legs[leg];
        Self {
            reference_rad: output.reference_rad,
            angle_rad: s.angle_rad,
            reference_velocity_rad_s: output.reference_velocity_rad_s,
            velocity_rad_s: s.velocity_rad_s,
            pressure_cmd_pa: *written,
            pressure_pa: s.pressure_pa,
            length_ref_m: output.length_ref_m,
            length_m: s.length_m,
            force_n: s.force_n,
            diagnostics: output.diagnostics,
            patient_nm: s.patient.total(),
            patient_parts_nm: s.patient,
            interaction_nm: s.interaction_nm,
            cuff_force_n: s.cuff_force_n,
            foot: state.ground.and_then(|g| {
                Some(FootSample {
                    reaction: *g.feet.get(leg)?,
                    reference_stance: output.reference_in_stance,
                    ankle_rad: s.ankle_rad,
                    ankle_torque_nm: s.ankle_torque_nm,
                })
            }),
        }
    }

    /// One leg's channels (after the time) for muscles named `muscles`, its foot's on a
    /// treadmill, as the CSV and Rerun show them.
    pub fn schema(muscles: &[String], treadmill: bool) -> Schema {
        let mut s = Schema::new();
        for j in JOINT_NAMES {
            s.push_part("joints", j, "reference_deg", "reference (deg)")
                .push_part("joints", j, "angle_deg", "angle (deg)")
                .push_part("joints", j, "error_deg", "error (deg)")
                .push_part(
                    "joints",
                    j,
                    "reference_velocity_deg_s",
                    "reference velocity (deg/s)",
                )
                .push_part("joints", j, "velocity_deg_s", "velocity (deg/s)")
                .push_part(
                    "joints",
                    j,
                    "patient_torque_nm",
                    "patient torque (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "reflex_torque_nm",
                    "patient's stretch reflex (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "spasm_torque_nm",
                    "spasm torque (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "effort_torque_nm",
                    "patient's voluntary effort (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "stiffness_torque_nm",
                    "patient's passive stiffness (N m, flexion +)",
                )
                .push_part(
                    "joints",
                    j,
                    "interaction_torque_nm",
                    "device's torque on the limb (N m, flexion +)",
                );
        }
        for m in muscles {
            s.push_part("muscles", m, "pressure_cmd_pa", "pressure command (Pa)")
                .push_part("muscles", m, "pressure_pa", "pressure (Pa)")
                .push_part("muscles", m, "length_ref_m", "contraction reference (m)")
                .push_part("muscles", m, "length_m", "contraction (m)")
                .push_part("muscles", m, "force_n", "force (N)")
                .push_part("muscles", m, "proxy_m", "proxy position (m)")
                .push_part("muscles", m, "s_p", "S_p (m/s)")
                .push_part("muscles", m, "s_q", "S_q (m/s)")
                .push_part("muscles", m, "gain_hat", "adaptive gain")
                .push_part(
                    "muscles",
                    m,
                    "disturbance_hat",
                    "disturbance estimate (m/s^2)",
                );
        }
        for cuff in ["thigh_cuff", "shank_cuff"] {
            s.push_part(
                "cuffs",
                cuff,
                "force_n",
                "force on the limb (N, perpendicular to the segment, forward +)",
            );
        }
        if treadmill {
            s.channels.extend(Self::foot_schema().channels);
        }
        s
    }

    /// The foot's and the passive ankle's channels of a leg on a treadmill (after the
    /// joints' and the muscles' in [`Self::schema`]).
    pub fn foot_schema() -> Schema {
        let mut s = Schema::new();
        s.push_part(
            "ground",
            "foot",
            "grf_vertical_n",
            "vertical ground reaction force (N)",
        )
        .push_part(
            "ground",
            "foot",
            "grf_fore_aft_n",
            "fore-aft ground reaction force (N, forward +)",
        )
        .push_part(
            "ground",
            "foot",
            "stance",
            "in stance (1, from contact) or swing (0)",
        )
        .push_part(
            "ground",
            "foot",
            "reference_stance",
            "in the reference's stance (1) or swing (0)",
        )
        .push_part("ground", "foot", "slip_m_s", "slip on the belt (m/s)")
        .push_part(
            "ground",
            "foot",
            "penetration_m",
            "deepest sphere penetration (m)",
        )
        .push_part(
            "joints",
            "ankle",
            "angle_deg",
            "angle (deg, dorsiflexion +; passive)",
        )
        .push_part(
            "joints",
            "ankle",
            "orthosis_torque_nm",
            "orthosis torque (N m, dorsiflexion +)",
        );
        s
    }

    /// Writes the leg's values in the order of [`Self::schema`].
    fn put(&self, put: &mut impl FnMut(f64)) {
        for j in 0..2 {
            let (r, a) = (
                self.reference_rad[j].to_degrees(),
                self.angle_rad[j].to_degrees(),
            );
            let p = &self.patient_parts_nm;
            for v in [
                r,
                a,
                r - a,
                self.reference_velocity_rad_s[j].to_degrees(),
                self.velocity_rad_s[j].to_degrees(),
                self.patient_nm[j],
                p.reflex_nm[j],
                p.spasm_nm[j],
                p.effort_nm[j],
                p.stiffness_nm[j],
                self.interaction_nm[j],
            ] {
                put(v);
            }
        }
        for i in 0..4 {
            let d = &self.diagnostics[i];
            for v in [
                self.pressure_cmd_pa[i],
                self.pressure_pa[i],
                self.length_ref_m[i],
                self.length_m[i],
                self.force_n[i],
                d.proxy_position_m,
                d.s_p,
                d.s_q,
                d.gain_hat,
                d.disturbance_hat,
            ] {
                put(v);
            }
        }
        for f in self.cuff_force_n {
            put(f);
        }
        if let Some(f) = self.foot {
            let g = f.reaction;
            let stance = g.vertical_n > crate::metrics::CONTACT_THRESHOLD_N;
            for v in [
                g.vertical_n,
                g.fore_aft_n,
                f64::from(u8::from(stance)),
                f64::from(u8::from(f.reference_stance)),
                g.slip_m_s,
                g.penetration_m,
                f.ankle_rad.to_degrees(),
                f.ankle_torque_nm,
            ] {
                put(v);
            }
        }
    }
}

impl TrainerSample {
    /// The exoskeleton's view of one loop period.
    pub fn of(p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) -> Self {
        let s = p.truth;
        Self {
            t_s: p.t_s,
            legs: PerLeg::from_fn(s.legs.len(), |leg| {
                LegSample::of(s, leg, &p.output[leg], &p.written[leg])
            }),
            ground: s.ground.map(|g| GroundSample {
                other_leg_n: g.contralateral_n,
                support_n: g.support_n,
                harness_fore_aft_n: g.harness_fore_aft_n,
                pelvis_m: s.pelvis_m.unwrap_or([f64::NAN; 2]),
            }),
        }
    }

    /// The treadmill's channels of the pelvis and what holds it.
    pub fn ground_schema() -> Schema {
        let mut s = Schema::new();
        s.push_part(
            "ground",
            "other_leg",
            "force_n",
            "(virtual) force on the pelvis (N)",
        )
        .push_part(
            "ground",
            "harness",
            "force_n",
            "body-weight support force (N)",
        )
        .push_part(
            "ground",
            "harness",
            "fore_aft_n",
            "fore-aft force on the pelvis (N, forward +)",
        )
        .push_part(
            "ground",
            "pelvis",
            "x_m",
            "fore-aft position (m, forward +)",
        )
        .push_part("ground", "pelvis", "height_m", "height above the belt (m)");
        s
    }

    /// The channels (after the time) of a trainer of `legs` legs whose muscles (one leg's)
    /// are named `muscles`, on a treadmill or not, as the CSV and Rerun show them: each
    /// leg's (prefixed by its side when there are two), then the pelvis's.
    pub fn schema(muscles: &[String], legs: usize, treadmill: bool) -> Schema {
        let leg = LegSample::schema(muscles, treadmill);
        let mut s = Schema::new();
        for side in SIDES.iter().take(legs) {
            let part = if legs > 1 {
                leg.prefixed(side)
            } else {
                leg.clone()
            };
            s.channels.extend(part.channels);
        }
        if treadmill {
            s.channels.extend(Self::ground_schema().channels);
        }
        s
    }
}

impl Signals for TrainerSample {
    fn values(&self, out: &mut [f64]) {
        let mut k = 0;
        let mut put = |v: f64| {
            out[k] = v;
            k += 1;
        };
        for leg in &self.legs {
            leg.put(&mut put);
        }
        if let Some(g) = self.ground {
            for v in [
                g.other_leg_n,
                g.support_n,
                g.harness_fore_aft_n,
                g.pelvis_m[0],
                g.pelvis_m[1],
            ] {
                put(v);
            }
        }
    }
}
