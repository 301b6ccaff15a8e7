//! What a run did to the patient and to the hardware: the patient's torques, each spasm's
//! effect on tracking, time beyond the joint limits, muscle forces against their rating and
//! valve saturation; accumulated by a [`Recorder`] whose buffers are sized before the run.
use crate::base::JOINT_NAMES;
use crate::metrics::{LegPeriod, LegRecorder, LegStart};
use crate::patient::{SpasmDirection, SpasmEvent};
use crate::plant::LegPlant;
use std::collections::BTreeMap;

/// Error within which a joint counts as recovered after a spasm (deg).
pub const RECOVERED_DEG: f64 = 1.0;
/// How long after its end a spasm is followed, unless another one starts (s).
pub const FOLLOW_S: f64 = 3.0;
/// Angle beyond a joint limit that counts as outside it (deg): rapier's limits are stiff
/// constraints that a hard push can enter by a hair.
pub const LIMIT_TOLERANCE_DEG: f64 = 0.1;

/// The normal range of motion of hip and knee (deg, flexion positive): hip 30 deg of
/// extension to 120 of flexion, knee 0 (full extension) to 135 of flexion, the American
/// Academy of Orthopaedic Surgeons' averages (Greene and Heckman 1994, The Clinical
/// Measurement of Joint Motion; as tabulated by Soucie et al. 2011, Haemophilia 17:500).
/// A patient moved beyond it is hurt whatever the exoskeleton's own stops allow.
pub const NORMAL_RANGE_DEG: [[f64; 2]; 2] = [[-30.0, 120.0], [0.0, 135.0]];

/// The patient's torque at one joint over the run.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PatientJointStats {
    /// RMS (N m).
    pub torque_rms_nm: f64,
    /// Largest magnitude (N m).
    pub torque_peak_nm: f64,
}

/// The patient's torques, hip and knee.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
#[serde(transparent)]
pub struct PatientReport {
    /// Per joint (`hip`, `knee`; `right/hip`, ... on a two-leg trainer).
    pub joints: BTreeMap<String, PatientJointStats>,
}

/// One spasm and what it did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SpasmReport {
    /// `hip` or `knee`.
    pub joint: String,
    /// Onset (s).
    pub t_s: f64,
    /// `flexor` or `extensor`.
    pub direction: SpasmDirection,
    /// Peak torque (N m).
    pub amplitude_nm: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// Largest deviation of its joint from onset to the end of the follow-up (deg): of the
    /// tracking error from the same run's without the spasms when `against_baseline`,
    /// else of the tracking error itself.
    pub peak_deviation_deg: f64,
    /// Largest |angular velocity| of its joint beyond the same run's without the spasms
    /// (deg/s) when `against_baseline`, else its largest |angular velocity|.
    pub peak_joint_speed_deg_s: f64,
    /// Largest |dp/dt| of its joint's two muscles (bar/s).
    pub peak_pressure_rate_bar_s: f64,
    /// From the spasm's end until the error is back within 1 deg for good (s); `null` if it
    /// still was not at the end of the follow-up, or if the next spasm of the joint began
    /// before this one ended.
    pub recovery_s: Option<f64>,
    /// The next spasm of the same joint began before this one ended: its figures cover
    /// this one only until then.
    pub overlapped: bool,
    /// End of the follow-up (s): [`FOLLOW_S`] after the spasm, the next spasm or the run's end.
    pub followed_until_s: f64,
    /// Whether deviation, joint speed and recovery are measured against the same run
    /// without the spasms (same seeds and controllers; `false` only for a simulation
    /// continued from an earlier run or modified after it was built).
    pub against_baseline: bool,
}

/// A joint against its URDF limits and the normal range of motion.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct LimitStats {
    /// Time beyond a URDF limit by more than [`LIMIT_TOLERANCE_DEG`] (s).
    pub time_outside_s: f64,
    /// Largest angle beyond a URDF limit (deg; 0 if never).
    pub max_beyond_deg: f64,
    /// Time beyond the normal range of motion ([`NORMAL_RANGE_DEG`]) by more than
    /// [`LIMIT_TOLERANCE_DEG`] (s).
    pub time_beyond_normal_range_s: f64,
    /// Largest angle beyond the normal range of motion (deg; negative: the smallest margin
    /// to it).
    pub beyond_normal_range_deg: f64,
}

/// A muscle against its rating and its valve's range.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct MuscleSafety {
    /// Largest force (N).
    pub peak_force_n: f64,
    /// The muscle's rated force (N): its Festo size's, or Table I's own pull at the valve's
    /// limit for an eq. (1) muscle (`plant.muscle_rated_force_n` overrides it).
    pub rated_force_n: f64,
    /// What the rating is (`Festo DMSP-40`, `Table I's muscle at 6.0 bar, ...`).
    pub rating: String,
    /// `peak_force_n / rated_force_n`.
    pub peak_over_rated: f64,
    /// Time the force was above the rating (s).
    pub time_over_rated_s: f64,
    /// `rated_force_n - peak_force_n` (N): negative when the rating was exceeded.
    pub margin_n: f64,
    /// Time the controller's command sat at 0 or at the valve's maximum (s).
    pub valve_saturated_s: f64,
    /// Time its command was lowered to its force limit (s; `[control] force_max_of_rating`,
    /// 0 without one).
    pub force_limited_s: f64,
    /// Largest |dp/dt| of the muscle's pressure over the run (bar/s).
    pub peak_pressure_rate_bar_s: f64,
}

/// Safety figures of a run.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct SafetyReport {
    /// Per joint.
    pub joints: BTreeMap<String, LimitStats>,
    /// Per muscle.
    pub muscles: BTreeMap<String, MuscleSafety>,
}

impl SafetyReport {
    /// Each muscle whose peak force exceeded `max` times its rating, or whose ratio the run
    /// could not give (NaN: a force nobody can vouch for is not within a rating), as
    /// `name 1.15x`; empty when every muscle stayed within it.
    pub fn over_rating(&self, max: f64) -> Vec<String> {
        self.muscles
            .iter()
            .filter(|(_, m)| m.peak_over_rated.is_nan() || m.peak_over_rated > max)
            .map(|(name, m)| format!("{name} {}x", crate::metrics::figure(m.peak_over_rated, 2)))
            .collect()
    }
}

#[derive(Debug, Clone)]
struct SpasmAcc {
    event: SpasmEvent,
    overlapped: bool,
    until_s: f64,
    peak_dev: f64,
    peak_speed: f64,
    peak_rate: f64,
    last_out_s: Option<f64>,
    out_at_end: bool,
}

/// Accumulates the patient, spasm and safety figures.
#[derive(Debug, Clone)]
pub struct PatientMetrics {
    joint_of: [usize; 4],
    limits_rad: [[f64; 2]; 2],
    pressure_max_pa: f64,
    rated_force_n: [f64; 4],
    rating: [String; 4],
    n: usize,
    torque_sq: [f64; 2],
    torque_peak: [f64; 2],
    spasms: Vec<SpasmAcc>,
    first_open: usize,
    outside_s: [f64; 2],
    beyond: [f64; 2],
    outside_normal_s: [f64; 2],
    beyond_normal: [f64; 2],
    peak_force: [f64; 4],
    over_rated_s: [f64; 4],
    saturated_s: [f64; 4],
    force_limited_s: [f64; 4],
    peak_rate: [f64; 4],
    previous_p: [f64; 4],
    /// The same run without its spasms: per period, the joints' errors (deg) and velocities
    /// (deg/s).
    baseline: Option<Vec<[f64; 4]>>,
    period: usize,
}

/// Records, per period, the joints' tracking errors (deg) and velocities (deg/s): a run's
/// baseline for its spasms.
#[derive(Debug, Default)]
pub struct BaselineTrace(pub Vec<[f64; 4]>);

impl LegRecorder for BaselineTrace {
    fn record(&mut self, p: &LegPeriod<'_>) {
        let s = p.state;
        let e = |j: usize| (p.output.reference_rad[j] - s.angle_rad[j]).to_degrees();
        let w = |j: usize| s.velocity_rad_s[j].to_degrees();
        self.0.push([e(0), e(1), w(0), w(1)]);
    }
}

impl PatientMetrics {
    /// Figures for `plant`'s leg over a run ending at `end_s`, following `events` (the
    /// spasms of the run); each muscle against its own rating.
    pub fn new(
        plant: &LegPlant,
        leg: usize,
        events: &[SpasmEvent],
        end_s: f64,
        pressure_max_pa: f64,
        baseline: Option<Vec<[f64; 4]>>,
    ) -> Self {
        let muscles = plant.leg_muscles(leg);
        let joint_of = std::array::from_fn(|i| muscles.get(i).map_or(0, |m| m.joint));
        let rated_force_n =
            std::array::from_fn(|i| muscles.get(i).map_or(f64::NAN, |m| m.rated_force_n));
        let rating = std::array::from_fn(|i| {
            muscles
                .get(i)
                .map_or_else(String::new, |m| m.rating.clone())
        });
        let spasms = events
            .iter()
            .enumerate()
            .map(|(i, e)| {
                // Followed until the next spasm of the same joint: one on the other joint
                // does not end this one's effect.
                let next = events[i + 1..]
                    .iter()
                    .find(|n| n.joint == e.joint)
                    .map_or(f64::INFINITY, |n| n.t_s);
                SpasmAcc {
                    event: *e,
                    overlapped: next < e.end_s(),
                    until_s: (e.end_s() + FOLLOW_S).min(next).min(end_s),
                    peak_dev: 0.0,
                    peak_speed: 0.0,
                    peak_rate: 0.0,
                    last_out_s: None,
                    out_at_end: false,
                }
            })
            .collect();
        Self {
            joint_of,
            limits_rad: plant.exo().limits_rad(leg),
            pressure_max_pa,
            rated_force_n,
            rating,
            n: 0,
            torque_sq: [0.0; 2],
            torque_peak: [0.0; 2],
            spasms,
            first_open: 0,
            outside_s: [0.0; 2],
            beyond: [0.0; 2],
            outside_normal_s: [0.0; 2],
            beyond_normal: [f64::NEG_INFINITY; 2],
            peak_force: [0.0; 4],
            over_rated_s: [0.0; 4],
            saturated_s: [0.0; 4],
            force_limited_s: [0.0; 4],
            peak_rate: [0.0; 4],
            previous_p: [f64::NAN; 4],
            baseline,
            period: 0,
        }
    }

    fn push_spasms(&mut self, t: f64, error_deg: [f64; 2], speed_deg_s: [f64; 2], rate: [f64; 4]) {
        while self
            .spasms
            .get(self.first_open)
            .is_some_and(|s| s.until_s < t)
        {
            self.first_open += 1;
        }
        for s in self.spasms[self.first_open..].iter_mut() {
            if s.event.t_s > t {
                break;
            }
            if t > s.until_s {
                continue;
            }
            let j = s.event.joint;
            let e = error_deg[j].abs();
            s.peak_dev = s.peak_dev.max(e);
            s.peak_speed = s.peak_speed.max(speed_deg_s[j].abs());
            for (i, r) in rate.iter().enumerate() {
                if self.joint_of[i] == j && r.is_finite() {
                    s.peak_rate = s.peak_rate.max(r.abs());
                }
            }
            let out = e > RECOVERED_DEG;
            if out {
                s.last_out_s = Some(t);
            }
            s.out_at_end = out;
        }
    }

    /// The patient's torque figures.
    pub fn patient(&self) -> PatientReport {
        let stats = |j: usize| PatientJointStats {
            torque_rms_nm: if self.n > 0 {
                (self.torque_sq[j] / self.n as f64).sqrt()
            } else {
                0.0
            },
            torque_peak_nm: self.torque_peak[j],
        };
        PatientReport {
            joints: JOINT_NAMES
                .iter()
                .enumerate()
                .map(|(j, n)| ((*n).to_owned(), stats(j)))
                .collect(),
        }
    }

    /// Each spasm of the run that has started, by onset.
    pub fn spasms(&self, t_end_s: f64) -> Vec<SpasmReport> {
        self.spasms
            .iter()
            .filter(|s| s.event.t_s <= t_end_s)
            .map(|s| {
                let until = s.until_s.min(t_end_s);
                SpasmReport {
                    joint: JOINT_NAMES[s.event.joint].to_owned(),
                    t_s: s.event.t_s,
                    direction: s.event.direction,
                    amplitude_nm: s.event.amplitude_nm,
                    duration_s: s.event.duration_s,
                    peak_deviation_deg: s.peak_dev,
                    peak_joint_speed_deg_s: s.peak_speed,
                    peak_pressure_rate_bar_s: s.peak_rate / 1e5,
                    recovery_s: if s.out_at_end || s.overlapped || until < s.event.end_s() {
                        None
                    } else {
                        Some(s.last_out_s.map_or(0.0, |t| (t - s.event.end_s()).max(0.0)))
                    },
                    overlapped: s.overlapped,
                    followed_until_s: until,
                    against_baseline: self.baseline.is_some(),
                }
            })
            .collect()
    }

    /// Limits, forces and saturation, with the muscles' names in the geometry's order.
    pub fn safety(&self, muscle_names: &[String]) -> SafetyReport {
        SafetyReport {
            joints: JOINT_NAMES
                .iter()
                .enumerate()
                .map(|(j, n)| {
                    (
                        (*n).to_owned(),
                        LimitStats {
                            time_outside_s: self.outside_s[j],
                            max_beyond_deg: self.beyond[j],
                            time_beyond_normal_range_s: self.outside_normal_s[j],
                            beyond_normal_range_deg: self.beyond_normal[j],
                        },
                    )
                })
                .collect(),
            muscles: muscle_names
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    (
                        name.clone(),
                        MuscleSafety {
                            peak_force_n: self.peak_force[i],
                            rated_force_n: self.rated_force_n[i],
                            rating: self.rating[i].clone(),
                            peak_over_rated: self.peak_force[i] / self.rated_force_n[i],
                            time_over_rated_s: self.over_rated_s[i],
                            margin_n: self.rated_force_n[i] - self.peak_force[i],
                            valve_saturated_s: self.saturated_s[i],
                            force_limited_s: self.force_limited_s[i],
                            peak_pressure_rate_bar_s: self.peak_rate[i] / 1e5,
                        },
                    )
                })
                .collect(),
        }
    }
}

impl LegRecorder for PatientMetrics {
    fn start(&mut self, s: &LegStart<'_>) {
        self.previous_p = s.state.pressure_pa;
    }

    fn record(&mut self, p: &LegPeriod<'_>) {
        let s = p.state;
        let dt = p.dt_s;
        let tau = s.patient.total();
        self.n += 1;
        for (j, t) in tau.iter().enumerate() {
            self.torque_sq[j] += t * t;
            self.torque_peak[j] = self.torque_peak[j].max(t.abs());
            let [lo, hi] = self.limits_rad[j];
            let beyond = (lo - s.angle_rad[j]).max(s.angle_rad[j] - hi).to_degrees();
            if beyond > LIMIT_TOLERANCE_DEG {
                self.outside_s[j] += dt;
            }
            self.beyond[j] = self.beyond[j].max(beyond);
            let [lo, hi] = NORMAL_RANGE_DEG[j];
            let angle = s.angle_rad[j].to_degrees();
            let beyond_normal = (lo - angle).max(angle - hi);
            if beyond_normal > LIMIT_TOLERANCE_DEG {
                self.outside_normal_s[j] += dt;
            }
            self.beyond_normal[j] = self.beyond_normal[j].max(beyond_normal);
        }
        let rate: [f64; 4] = std::array::from_fn(|i| (s.pressure_pa[i] - self.previous_p[i]) / dt);
        for (i, r) in rate.iter().enumerate() {
            self.peak_force[i] = self.peak_force[i].max(s.force_n[i]);
            if s.force_n[i] > self.rated_force_n[i] {
                self.over_rated_s[i] += dt;
            }
            if r.is_finite() {
                self.peak_rate[i] = self.peak_rate[i].max(r.abs());
            }
            let u = p.output.pressure_cmd_pa[i];
            if u <= 1.0 || u >= self.pressure_max_pa - 1.0 {
                self.saturated_s[i] += dt;
            }
            if p.output.force_limited[i] {
                self.force_limited_s[i] += dt;
            }
        }
        // Against the run without spasms, period by period, when there is one.
        let base = self
            .baseline
            .as_ref()
            .and_then(|b| b.get(self.period))
            .copied()
            .unwrap_or([0.0; 4]);
        self.period += 1;
        let error_deg: [f64; 2] = std::array::from_fn(|j| {
            (p.output.reference_rad[j] - s.angle_rad[j]).to_degrees() - base[j]
        });
        let speed: [f64; 2] =
            std::array::from_fn(|j| s.velocity_rad_s[j].to_degrees() - base[2 + j]);
        self.push_spasms(p.t_s, error_deg, speed, rate);
        self.previous_p = s.pressure_pa;
    }
}
