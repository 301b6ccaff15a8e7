//! Gait on the treadmill, phase by phase: stance and swing detected from the foot's
//! contact, the vertical ground reaction force (GRF) of every stride (peak, loading rate
//! at heel strike), the stance fraction against the reference's, the foot's slip on the
//! belt, tracking per phase, and each heel strike as a shock; accumulated by a
//! [`Recorder`] whose buffers are sized before the run.
use crate::base::{PerLeg, JOINT_NAMES, SIDES};
use crate::body::Exoskeleton;
use crate::control::LegOutput;
use crate::gait::{loading, GaitReference, Loading};
use crate::ground::{FootReaction, GroundReaction};
use crate::metrics::{LegPeriod, LegRecorder};
use crate::plant::SupervisedLeg;
use pma_loop::{Period, Recorder};
use std::collections::BTreeMap;

/// Vertical GRF above which the foot is in stance (N): the usual force-plate threshold
/// for gait events (10-20 N); well above the contact model's noise, well below a step.
pub const CONTACT_THRESHOLD_N: f64 = 20.0;

/// Shortest swing that separates two stances (s): a foot that bounces off the belt for a
/// few milliseconds at heel strike has not taken a step.
pub const MIN_SWING_S: f64 = 0.05;

/// How long after a heel strike its shock is followed (s): the loading response lasts
/// about the first 10 % of the cycle (0.16 s at a 1.6 s stride); twice that.
pub const HEEL_STRIKE_FOLLOW_S: f64 = 0.3;

/// Error growth within which a joint counts as recovered from a heel strike (deg), as
/// [`crate::metrics::RECOVERED_DEG`] for a spasm.
pub const HEEL_STRIKE_RECOVERED_DEG: f64 = 1.0;

/// A "stride" shorter than this share of the reference's is no stride: the swing foot
/// touched the belt (a scuff) and lifted again before its heel strike. It is merged into
/// the stride it interrupted and counted as a scuff. (At 90-95 % support the stance foot
/// loads the belt over the 20 N threshold in two pieces; the second is merged so.)
pub const SCUFF_MAX_STRIDE_SHARE: f64 = 0.5;

/// A contact shorter than this share of the reference's stance is a scuff, however long
/// the "stride" it would open: an adult's stance lasts 60-68 % of the cycle at 0.5-1.2 m/s
/// (Fukuchi et al. 2018; 67.5 % in the shipped reference, 1.18 s at the 1.754 s stride).
/// A quarter, not a half: at 90-95 % support the foot loads the belt over the 20 N
/// threshold for only 0.30-0.32 of the cycle (0.53-0.56 s) in one or two pieces, and those
/// are stances; a swing toe's drag that loads the foot more than a touch does is caught by
/// [`SCUFF_MAX_LOAD_SHARE`] (0.33 s of 0.15 BW unsupported: issue 47).
pub const SCUFF_MAX_STANCE_SHARE: f64 = 0.25;

/// A contact whose loading peak stays under this share of the weight the belt carries,
/// `(1 - bws_fraction)` times the patient's, is a scuff: a stance's loading peak reaches
/// 1.0-1.25 times that weight (the adults' loading response, Fukuchi et al. 2018; 1.21-1.24
/// on the unsupported trainer), a dragging toe 0.15 (issue 47).
pub const SCUFF_MAX_LOAD_SHARE: f64 = 0.5;

/// Smallest, mean and largest of a figure over the strides.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(values: impl Iterator<Item = f64> + Clone) -> Self {
        let n = values.clone().count();
        if n == 0 {
            return Self {
                mean: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            };
        }
        let (sum, min, max) = values.fold((0.0, f64::INFINITY, f64::NEG_INFINITY), |a, v| {
            (a.0 + v, a.1.min(v), a.2.max(v))
        });
        Self {
            mean: sum / n as f64,
            min,
            max,
        }
    }
}

/// One stride, heel strike to heel strike.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StrideReport {
    /// Heel strike (s).
    pub t_s: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// Largest vertical GRF in the first half of stance: the loading peak (body weights).
    pub peak_grf_bw: f64,
    /// Mean slope of the vertical GRF from 20 % to 80 % of that peak (body weights per s).
    pub loading_rate_bw_s: f64,
    /// Stance time over the stride's.
    pub stance_fraction: f64,
    /// Distance the foot slipped on the belt during stance (m).
    pub slip_m: f64,
}

/// Tracking error of a joint in each phase, after the first stride (deg, RMS).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PhaseTracking {
    /// While the foot is on the belt.
    pub stance_rms_deg: f64,
    /// While it swings.
    pub swing_rms_deg: f64,
}

/// What the heel strikes did to a joint.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct HeelStrikeStats {
    /// Heel strikes followed.
    pub count: usize,
    /// Growth of |tracking error| within [`HEEL_STRIKE_FOLLOW_S`] of the strike, beyond
    /// its value at the strike (deg).
    pub deviation_deg: Spread,
    /// From the strike until the error is back within 1 deg of its value at the strike
    /// for good (s), over the strikes that recovered within the follow-up.
    pub recovery_s: Spread,
    /// Strikes whose error was still more than 1 deg above its value at the strike at
    /// the end of the follow-up.
    pub not_recovered: usize,
    /// Largest |dp/dt| of the joint's muscles within the follow-ups (bar/s).
    pub peak_pressure_rate_bar_s: f64,
}

/// One foot's figures of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FootReport {
    /// Complete strides after the first (heel strike to heel strike).
    pub strides: usize,
    /// Loading peak of the vertical GRF per stride (body weights).
    pub peak_grf_bw: Spread,
    /// Loading rate at heel strike per stride (body weights per second).
    pub loading_rate_bw_s: Spread,
    /// Stance fraction per stride, detected from contact.
    pub stance_fraction: Spread,
    /// The reference's stance fraction (its toe-off phase).
    pub reference_stance_fraction: f64,
    /// Mean vertical GRF over the counted strides (body weights).
    pub mean_grf_bw: f64,
    /// Distance the foot slipped on the belt per stride, in stance (m).
    pub slip_per_stride_m: Spread,
    /// Mean slip speed in stance (m/s).
    pub mean_stance_slip_m_s: f64,
    /// Deepest penetration into the belt (mm).
    pub max_penetration_mm: f64,
    /// The passive ankle's smallest and largest angle after the first stride (deg,
    /// dorsiflexion positive; NaN for a fixed ankle).
    pub ankle_range_deg: [f64; 2],
    /// Tracking error per phase and joint (deg, RMS).
    pub tracking: BTreeMap<String, PhaseTracking>,
    /// What the heel strikes did to each joint.
    pub heel_strikes: BTreeMap<String, HeelStrikeStats>,
    /// Every counted stride.
    pub per_stride: Vec<StrideReport>,
    /// Times the swing foot touched the belt and lifted again before its heel strike (a
    /// contact that would make a stride shorter than [`SCUFF_MAX_STRIDE_SHARE`] of the
    /// reference's, briefer than [`SCUFF_MAX_STANCE_SHARE`] of its stance or lighter than
    /// [`SCUFF_MAX_LOAD_SHARE`] of the belt's load); each is merged into the stride it
    /// interrupted, none is a stride.
    pub scuffs: usize,
}

/// The treadmill's figures of a run: the belt, the harness, the pelvis and every foot.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TreadmillReport {
    /// Belt speed (m/s): its mean after the first stride (a self-paced belt's changes).
    pub belt_speed_m_s: f64,
    /// Fraction of the system's weight the harness carries.
    pub bws_fraction: f64,
    /// The patient's body weight (N): the unit of the GRF figures (`*_bw`).
    pub body_weight_n: f64,
    /// The patient's height (m; the frame's legs are adjusted to it).
    pub height_m: f64,
    /// The system's weight over the patient's (exoskeleton included).
    pub system_weight_bw: f64,
    /// Legs on the belt.
    pub legs: usize,
    /// Mean vertical force the belt carries after the first stride: every foot's and a
    /// virtual other leg's (body weights).
    pub mean_belt_load_bw: f64,
    /// What it must carry on average: `(1 - bws_fraction) x system weight` (body weights).
    pub expected_belt_load_bw: f64,
    /// The virtual other leg's mean force (body weights; 0 without one).
    pub mean_other_leg_bw: f64,
    /// The pelvis's vertical excursion after the first stride (m).
    pub pelvis_excursion_m: f64,
    /// The pelvis's fore-aft excursion after the first stride (m).
    pub pelvis_fore_aft_excursion_m: f64,
    /// Share of the time the pelvis rests against a stop of its fore-aft slide (0-1): the
    /// stop, not the harness, then holds the trainer against the belt, with a force no
    /// output measures.
    pub pelvis_at_fore_aft_stop: f64,
    /// The harness's mean and largest fore-aft force on the pelvis after the first stride
    /// (N, forward positive): what the legs push the body with.
    pub harness_fore_aft_n: Spread,
    /// Each foot's figures, by side.
    pub feet: BTreeMap<String, FootReport>,
}

#[derive(Debug, Clone, Copy)]
struct StrideSums {
    /// Of this foot's vertical GRF (N s).
    impulse_n_s: f64,
    duration_s: f64,
    stance_s: f64,
    /// Of the slip speed in stance (m).
    slip_m: f64,
}

impl Default for StrideSums {
    fn default() -> Self {
        Self {
            impulse_n_s: 0.0,
            duration_s: 0.0,
            stance_s: 0.0,
            slip_m: 0.0,
        }
    }
}

impl StrideSums {
    fn add(&mut self, o: &StrideSums) {
        self.impulse_n_s += o.impulse_n_s;
        self.duration_s += o.duration_s;
        self.stance_s += o.stance_s;
        self.slip_m += o.slip_m;
    }
}

/// A heel strike being followed.
#[derive(Debug, Clone, Copy)]
struct Strike {
    t_s: f64,
    error0_deg: [f64; 2],
    worst_deg: [f64; 2],
    last_out_s: [Option<f64>; 2],
    out_at_end: [bool; 2],
    peak_rate: [f64; 2],
}

/// Accumulates the [`TreadmillReport`].
#[derive(Debug, Clone)]
pub struct FootMetrics {
    stride_s: f64,
    period_s: f64,
    reference_stance: f64,
    body_weight_n: f64,
    /// The loading peak under which a contact is a scuff (N; [`SCUFF_MAX_LOAD_SHARE`]).
    scuff_load_n: f64,
    joint_of: [usize; 4],
    /// The ankle's smallest and largest angle after the first stride (rad).
    ankle_rad: [f64; 2],
    in_stance: bool,
    /// When the foot last left the belt (s).
    left_s: f64,
    /// Heel strike of the stride under way, and its toe-off.
    stride_start_s: Option<f64>,
    toe_off_s: Option<f64>,
    /// The stride's vertical GRF, one value per period (sized for three strides).
    grf: Vec<f64>,
    /// The stride under way: its sums, added to the run's when it completes.
    stride: StrideSums,
    strides: Vec<StrideReport>,
    /// Contacts in swing merged into their stride (see [`SCUFF_MAX_STANCE_SHARE`]).
    scuffs: usize,
    strikes: Vec<Strike>,
    /// Sums over the counted strides.
    total: StrideSums,
    deepest_m: f64,
    phase_sq: [[f64; 2]; 2],
    phase_n: [[usize; 2]; 2],
    previous_p: [f64; 4],
}

impl FootMetrics {
    /// Figures for a foot of `exo` on its treadmill walking `gait` (its leg's), over a run
    /// of `duration_s` at `period_s`; `None` off a treadmill.
    pub fn new(
        exo: &Exoskeleton,
        gait: &GaitReference,
        duration_s: f64,
        period_s: f64,
    ) -> Option<Self> {
        let ground = exo.ground()?;
        let settings = ground.settings();
        let g = pma_model::GRAVITY_M_S2;
        let joint_of = JOINT_OF;
        let stride_s = gait.stride_period_s();
        let strides = (duration_s / stride_s).ceil() as usize + 2;
        Some(Self {
            stride_s,
            period_s,
            reference_stance: gait.toe_off_phase(),
            body_weight_n: settings.body_mass_kg * g,
            scuff_load_n: SCUFF_MAX_LOAD_SHARE
                * (1.0 - settings.bws_fraction)
                * settings.body_mass_kg
                * g,
            joint_of,
            ankle_rad: [f64::INFINITY, f64::NEG_INFINITY],
            in_stance: true,
            left_s: f64::NEG_INFINITY,
            stride_start_s: None,
            toe_off_s: None,
            grf: Vec::with_capacity((3.0 * stride_s / period_s) as usize + 1),
            stride: StrideSums::default(),
            strides: Vec::with_capacity(strides),
            scuffs: 0,
            strikes: Vec::with_capacity(strides),
            total: StrideSums::default(),
            deepest_m: 0.0,
            phase_sq: [[0.0; 2]; 2],
            phase_n: [[0; 2]; 2],
            previous_p: [f64::NAN; 4],
        })
    }

    /// Closes the stride that began at `start_s` with the heel strike at `t_s`.
    fn close_stride(&mut self, start_s: f64, t_s: f64) {
        let duration = t_s - start_s;
        let stance = self.toe_off_s.map_or(duration, |t| t - start_s);
        let bw = self.body_weight_n;
        let Loading { peak, rate } = loading(&self.grf, self.period_s, stance);
        let short = duration < SCUFF_MAX_STRIDE_SHARE * self.stride_s;
        let touch = stance < SCUFF_MAX_STANCE_SHARE * self.reference_stance * self.stride_s
            || peak < self.scuff_load_n;
        if (short || touch) && self.merge_scuff(start_s, t_s) {
            return;
        }
        if touch {
            // No stride to merge it into (it interrupted the first, uncounted one): a
            // scuff all the same, never a stride.
            self.drop_scuff(start_s);
            return;
        }
        // Strides whose heel strike falls in the first stride are not counted.
        if start_s >= self.stride_s && self.strides.len() < self.strides.capacity() {
            self.strides.push(StrideReport {
                t_s: start_s,
                duration_s: duration,
                peak_grf_bw: peak / bw,
                loading_rate_bw_s: rate / bw,
                stance_fraction: stance / duration,
                slip_m: self.stride.slip_m,
            });
            self.total.add(&self.stride);
        }
    }

    /// Merges the contact at `start_s`, which the heel strike at `t_s` shows was a scuff,
    /// into the stride it interrupted (the last counted one, which then ends at `t_s`; its
    /// stance is the one before the scuff) and drops its heel strike. False when there is
    /// no counted stride to merge into (before the first, the contact is not counted
    /// either).
    fn merge_scuff(&mut self, start_s: f64, t_s: f64) -> bool {
        let Some(last) = self.strides.last_mut() else {
            return false;
        };
        if (last.t_s + last.duration_s - start_s).abs() > 0.5 * self.period_s {
            return false;
        }
        let stance_s = last.stance_fraction * last.duration_s;
        last.duration_s = t_s - last.t_s;
        last.stance_fraction = stance_s / last.duration_s;
        last.slip_m += self.stride.slip_m;
        self.total.add(&self.stride);
        self.drop_scuff(start_s);
        true
    }

    /// Counts the contact at `start_s` as a scuff (after the first stride, as strides are)
    /// and drops its heel strike.
    fn drop_scuff(&mut self, start_s: f64) {
        if start_s >= self.stride_s {
            self.scuffs += 1;
        }
        if self
            .strikes
            .last()
            .is_some_and(|s| (s.t_s - start_s).abs() < 0.5 * self.period_s)
        {
            self.strikes.pop();
        }
    }

    fn heel_strike(&mut self, t_s: f64, error_deg: [f64; 2]) {
        if let Some(start) = self.stride_start_s {
            self.close_stride(start, t_s);
        }
        self.stride_start_s = Some(t_s);
        self.toe_off_s = None;
        self.grf.clear();
        self.stride = StrideSums::default();
        if t_s >= self.stride_s && self.strikes.len() < self.strikes.capacity() {
            self.strikes.push(Strike {
                t_s,
                error0_deg: error_deg.map(f64::abs),
                worst_deg: [0.0; 2],
                last_out_s: [None; 2],
                out_at_end: [false; 2],
                peak_rate: [0.0; 2],
            });
        }
    }

    fn follow_strike(&mut self, t_s: f64, error_deg: [f64; 2], rate: [f64; 4]) {
        let Some(s) = self.strikes.last_mut() else {
            return;
        };
        if t_s > s.t_s + HEEL_STRIKE_FOLLOW_S {
            return;
        }
        for (j, e) in error_deg.iter().enumerate() {
            let growth = e.abs() - s.error0_deg[j];
            s.worst_deg[j] = s.worst_deg[j].max(growth);
            let out = growth > HEEL_STRIKE_RECOVERED_DEG;
            if out {
                s.last_out_s[j] = Some(t_s);
            }
            s.out_at_end[j] = out;
        }
        for (i, r) in rate.iter().enumerate() {
            if r.is_finite() {
                let j = self.joint_of[i];
                s.peak_rate[j] = s.peak_rate[j].max(r.abs());
            }
        }
    }

    /// The report of the run so far.
    pub fn report(&self) -> FootReport {
        let bw = self.body_weight_n;
        let s = &self.strides;
        let t = &self.total;
        let rms = |j: usize, k: usize| {
            if self.phase_n[j][k] > 0 {
                (self.phase_sq[j][k] / self.phase_n[j][k] as f64).sqrt()
            } else {
                f64::NAN
            }
        };
        let tracking = JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(j, n)| {
                (
                    (*n).to_owned(),
                    PhaseTracking {
                        stance_rms_deg: rms(j, 0),
                        swing_rms_deg: rms(j, 1),
                    },
                )
            })
            .collect();
        let heel_strikes = JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(j, n)| ((*n).to_owned(), self.strike_stats(j)))
            .collect();
        FootReport {
            strides: s.len(),
            peak_grf_bw: Spread::of(s.iter().map(|r| r.peak_grf_bw)),
            loading_rate_bw_s: Spread::of(
                s.iter()
                    .map(|r| r.loading_rate_bw_s)
                    .filter(|v| v.is_finite()),
            ),
            stance_fraction: Spread::of(s.iter().map(|r| r.stance_fraction)),
            reference_stance_fraction: self.reference_stance,
            mean_grf_bw: if t.duration_s > 0.0 {
                t.impulse_n_s / t.duration_s / bw
            } else {
                f64::NAN
            },
            slip_per_stride_m: Spread::of(s.iter().map(|r| r.slip_m)),
            mean_stance_slip_m_s: if t.stance_s > 0.0 {
                t.slip_m / t.stance_s
            } else {
                f64::NAN
            },
            max_penetration_mm: self.deepest_m * 1e3,
            ankle_range_deg: if self.ankle_rad[1] >= self.ankle_rad[0] {
                self.ankle_rad.map(f64::to_degrees)
            } else {
                [f64::NAN; 2]
            },
            tracking,
            heel_strikes,
            per_stride: s.clone(),
            scuffs: self.scuffs,
        }
    }

    fn strike_stats(&self, j: usize) -> HeelStrikeStats {
        let strikes = &self.strikes;
        let recovered = strikes.iter().filter(|s| !s.out_at_end[j]);
        HeelStrikeStats {
            count: strikes.len(),
            deviation_deg: Spread::of(strikes.iter().map(|s| s.worst_deg[j])),
            recovery_s: Spread::of(recovered.map(|s| s.last_out_s[j].map_or(0.0, |t| t - s.t_s))),
            not_recovered: strikes.iter().filter(|s| s.out_at_end[j]).count(),
            peak_pressure_rate_bar_s: strikes
                .iter()
                .map(|s| s.peak_rate[j] / 1e5)
                .fold(0.0, f64::max),
        }
    }
}

/// What [`TreadmillMetrics`] takes from one period.
/// One period of one foot, as [`FootMetrics::push`] takes it.
#[derive(Debug, Clone, Copy)]
pub struct GroundPeriod {
    /// Time (s).
    pub t_s: f64,
    /// Period (s).
    pub dt_s: f64,
    /// The belt's reaction on the foot.
    pub foot: FootReaction,
    /// The leg's tracking errors (deg), hip and knee.
    pub error_deg: [f64; 2],
    /// The leg's muscle pressures (Pa; NaN without muscles).
    pub pressure_pa: [f64; 4],
    /// The ankle's angle (rad; NaN for a fixed ankle).
    pub ankle_rad: f64,
}

impl FootMetrics {
    /// One period.
    pub fn push(&mut self, p: &GroundPeriod) {
        let (t, dt, g, error_deg) = (p.t_s, p.dt_s, p.foot, p.error_deg);
        let rate: [f64; 4] = std::array::from_fn(|i| (p.pressure_pa[i] - self.previous_p[i]) / dt);
        self.previous_p = p.pressure_pa;
        let contact = g.vertical_n > CONTACT_THRESHOLD_N;
        if contact && !self.in_stance {
            if t - self.left_s >= MIN_SWING_S {
                self.heel_strike(t, error_deg);
            } else {
                // A bounce: the stance goes on.
                self.toe_off_s = None;
            }
            self.in_stance = true;
        } else if !contact && self.in_stance {
            self.in_stance = false;
            self.left_s = t;
            self.toe_off_s = Some(t);
        }
        if self.stride_start_s.is_some() {
            if self.grf.len() < self.grf.capacity() {
                self.grf.push(g.vertical_n);
            }
            let st = &mut self.stride;
            st.impulse_n_s += g.vertical_n * dt;
            st.duration_s += dt;
            if self.in_stance {
                st.stance_s += dt;
                st.slip_m += g.slip_m_s * dt;
            }
        }
        self.follow_strike(t, error_deg, rate);
        self.deepest_m = self.deepest_m.max(g.penetration_m);
        if t > self.stride_s {
            let phase = usize::from(!self.in_stance);
            for (j, e) in error_deg.iter().enumerate() {
                self.phase_sq[j][phase] += e * e;
                self.phase_n[j][phase] += 1;
            }
            if p.ankle_rad.is_finite() {
                self.ankle_rad = [
                    self.ankle_rad[0].min(p.ankle_rad),
                    self.ankle_rad[1].max(p.ankle_rad),
                ];
            }
        }
    }
}

impl LegRecorder for FootMetrics {
    fn record(&mut self, p: &LegPeriod<'_>) {
        let Some(ground) = p.trainer.ground else {
            return;
        };
        let Some(foot) = ground.feet.get(p.leg) else {
            return;
        };
        let s = p.state;
        self.push(&GroundPeriod {
            t_s: p.t_s,
            dt_s: p.dt_s,
            foot: *foot,
            error_deg: std::array::from_fn(|j| {
                (p.output.reference_rad[j] - s.angle_rad[j]).to_degrees()
            }),
            pressure_pa: s.pressure_pa,
            ankle_rad: s.ankle_rad,
        });
    }
}

/// Muscle `i` of a leg acts on joint `JOINT_OF[i]` in the shipped geometries' order; the
/// heel strikes' pressure rates are per joint.
const JOINT_OF: [usize; 4] = [0, 0, 1, 1];

/// The treadmill's figures that belong to no one foot: the belt's load, the harness and
/// the pelvis, after a given time (`size` and `fit-gait`:
/// [`GaitReference::measured_from_s`](crate::gait::GaitReference::measured_from_s);
/// `simulate`: the first stride).
#[derive(Debug, Clone)]
pub struct TrainerGroundMetrics {
    measured_from_s: f64,
    belt_speed_m_s: f64,
    bws_fraction: f64,
    body_weight_n: f64,
    height_m: f64,
    system_weight_n: f64,
    legs: usize,
    time_s: f64,
    /// How far the belt moved after the first stride (m).
    belt_travel_m: f64,
    belt_impulse_n_s: f64,
    other_impulse_n_s: f64,
    pelvis_z_m: [f64; 2],
    pelvis_x_m: [f64; 2],
    /// The pelvis's fore-aft stops (m, world X; `None` without a slide).
    stops_m: Option<[f64; 2]>,
    /// Time the pelvis spent against one (s).
    at_stop_s: f64,
    harness: (f64, f64, f64),
    active: bool,
}

/// How close to a fore-aft stop the pelvis counts as held by it (m).
const AT_STOP_M: f64 = 1e-3;

impl TrainerGroundMetrics {
    /// For `exo`'s treadmill (nothing off one), measured after `measured_from_s`.
    pub fn new(exo: &Exoskeleton, measured_from_s: f64) -> Self {
        let g = pma_model::GRAVITY_M_S2;
        let (active, speed, bws, body, system) = match exo.ground() {
            Some(ground) => {
                let s = ground.settings();
                (
                    true,
                    s.belt_speed_m_s(),
                    s.bws_fraction,
                    s.body_mass_kg * g,
                    ground.total_mass_kg() * g,
                )
            }
            None => (false, 0.0, 0.0, 1.0, 1.0),
        };
        let height_m = exo
            .ground()
            .and_then(|g| g.settings().height_m)
            .unwrap_or(crate::body::URDF_PATIENT_HEIGHT_M);
        Self {
            measured_from_s,
            belt_speed_m_s: speed,
            bws_fraction: bws,
            body_weight_n: body,
            height_m,
            system_weight_n: system,
            legs: exo.leg_count(),
            time_s: 0.0,
            belt_travel_m: 0.0,
            belt_impulse_n_s: 0.0,
            other_impulse_n_s: 0.0,
            pelvis_z_m: [f64::INFINITY, f64::NEG_INFINITY],
            pelvis_x_m: [f64::INFINITY, f64::NEG_INFINITY],
            stops_m: exo.ground().and_then(|g| g.fore_aft_stops_m()),
            at_stop_s: 0.0,
            harness: (0.0, f64::INFINITY, f64::NEG_INFINITY),
            active,
        }
    }

    /// The run's treadmill report with every foot's (in leg order); `None` off a treadmill.
    pub fn report(&self, feet: Vec<FootReport>) -> Option<TreadmillReport> {
        if !self.active {
            return None;
        }
        let bw = self.body_weight_n;
        let per = |v: f64| {
            if self.time_s > 0.0 {
                v / self.time_s
            } else {
                f64::NAN
            }
        };
        let range = |r: [f64; 2]| if r[1] >= r[0] { r[1] - r[0] } else { f64::NAN };
        Some(TreadmillReport {
            belt_speed_m_s: if self.time_s > 0.0 {
                self.belt_travel_m / self.time_s
            } else {
                self.belt_speed_m_s
            },
            bws_fraction: self.bws_fraction,
            body_weight_n: bw,
            height_m: self.height_m,
            system_weight_bw: self.system_weight_n / bw,
            legs: self.legs,
            mean_belt_load_bw: per(self.belt_impulse_n_s) / bw,
            expected_belt_load_bw: (1.0 - self.bws_fraction) * self.system_weight_n / bw,
            mean_other_leg_bw: per(self.other_impulse_n_s) / bw,
            pelvis_excursion_m: range(self.pelvis_z_m),
            pelvis_fore_aft_excursion_m: range(self.pelvis_x_m),
            pelvis_at_fore_aft_stop: match self.stops_m {
                Some(_) => per(self.at_stop_s),
                None => 0.0,
            },
            harness_fore_aft_n: Spread {
                mean: per(self.harness.0),
                min: self.harness.1,
                max: self.harness.2,
            },
            feet: feet
                .into_iter()
                .enumerate()
                .map(|(leg, f)| (SIDES[leg.min(SIDES.len() - 1)].to_owned(), f))
                .collect(),
        })
    }
}

impl Recorder<SupervisedLeg, PerLeg<LegOutput>> for TrainerGroundMetrics {
    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        if let (Some(g), Some(pelvis)) = (p.truth.ground, p.truth.pelvis_m) {
            self.push(p.t_s, p.dt_s, &g, pelvis);
        }
    }
}

impl TrainerGroundMetrics {
    /// One period of `dt` ending at `t_s`: the ground's reaction and the pelvis's position
    /// `[fore-aft, height]` (m).
    pub fn push(&mut self, t_s: f64, dt: f64, g: &GroundReaction, pelvis: [f64; 2]) {
        if t_s <= self.measured_from_s {
            return;
        }
        self.time_s += dt;
        self.belt_travel_m += g.belt_speed_m_s * dt;
        self.belt_impulse_n_s += g.belt_load_n() * dt;
        self.other_impulse_n_s += g.contralateral_n * dt;
        if let Some([lo, hi]) = self.stops_m {
            if pelvis[0] <= lo + AT_STOP_M || pelvis[0] >= hi - AT_STOP_M {
                self.at_stop_s += dt;
            }
        }
        self.pelvis_x_m = [
            self.pelvis_x_m[0].min(pelvis[0]),
            self.pelvis_x_m[1].max(pelvis[0]),
        ];
        self.pelvis_z_m = [
            self.pelvis_z_m[0].min(pelvis[1]),
            self.pelvis_z_m[1].max(pelvis[1]),
        ];
        let h = g.harness_fore_aft_n;
        self.harness = (
            self.harness.0 + h * dt,
            self.harness.1.min(h),
            self.harness.2.max(h),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::Mount;

    #[test]
    fn loading_rate_is_the_slope_from_20_to_80_percent_of_the_peak() {
        // A ramp to 1 over 100 ms, then flat: 20 % at 20 ms, 80 % at 80 ms, 0.6 over 60 ms.
        let dt_s = 1e-3;
        let grf: Vec<f64> = (0..600).map(|k| (k as f64 / 100.0).min(1.0)).collect();
        let l = loading(&grf, dt_s, 0.6);
        assert_eq!(l.peak, 1.0);
        assert!((l.rate - 10.0).abs() < 1e-9, "{}", l.rate);
        // The peak is looked for in the first half of stance only: a push-off peak later
        // does not count.
        let mut humps = grf.clone();
        humps[500] = 1.5;
        assert_eq!(loading(&humps, dt_s, 0.6).peak, 1.0);
        assert!(loading(&[0.0; 10], dt_s, 0.01).rate.is_nan());
    }

    /// A foot whose contact follows `grf_at(phase)` over `strides` strides of the
    /// scenario's gait, its report.
    fn foot_report(strides: usize, grf_at: impl Fn(f64) -> f64) -> FootReport {
        let loaded = crate::scenario::Scenario::load("gait_treadmill").expect("embedded");
        let exo = crate::sim::build_exo(&loaded, Mount::default()).expect("builds");
        let gait = loaded.scenario.gait.reference().expect("reference");
        let period_s = loaded.scenario.period_s;
        let duration_s = strides as f64 * gait.stride_period_s();
        let mut m = FootMetrics::new(&exo, &gait, duration_s, period_s).expect("a treadmill");
        for k in 1..=(duration_s / period_s).round() as usize {
            let t_s = k as f64 * period_s;
            let vertical_n = grf_at((t_s / gait.stride_period_s()).fract());
            m.push(&GroundPeriod {
                t_s,
                dt_s: period_s,
                foot: FootReaction {
                    vertical_n,
                    fore_aft_n: 0.0,
                    penetration_m: 0.0,
                    slip_m_s: 0.0,
                    fore_aft_slip_m_s: 0.0,
                    contacts: usize::from(vertical_n > 0.0),
                },
                error_deg: [0.0; 2],
                pressure_pa: [f64::NAN; 4],
                ankle_rad: f64::NAN,
            });
        }
        m.report()
    }

    #[test]
    fn regression_a_scuff_in_swing_is_no_stride() {
        // Under gains that let the toes touch the belt at 83 % of the cycle for 15-19 ms,
        // each scuff was counted as a heel strike: every stride split in two, the
        // stance reported as 0.455 of the cycle against 0.675 and the loading peak
        // halved. A stance to 67.5 % of the cycle and a 20 ms touch at 83 %:
        let stance = |phase: f64| if phase < 0.675 { 600.0 } else { 0.0 };
        let scuffing = |phase: f64| {
            if (0.83..0.84).contains(&phase) {
                50.0
            } else {
                stance(phase)
            }
        };
        let [clean, scuffed] = [foot_report(6, stance), foot_report(6, scuffing)];
        assert_eq!(clean.scuffs, 0);
        assert_eq!(scuffed.strides, clean.strides, "{scuffed:?}");
        assert!(scuffed.scuffs >= clean.strides, "{scuffed:?}");
        let gap = (scuffed.stance_fraction.mean - clean.stance_fraction.mean).abs();
        assert!(gap < 1e-9, "{gap}");
        assert!(
            (clean.stance_fraction.mean - 0.675).abs() < 0.01,
            "{clean:?}"
        );
        assert_eq!(scuffed.peak_grf_bw, clean.peak_grf_bw);
    }

    /// A foot in stance from half the cycle to 17.5 % of the next (its first contact
    /// after the first stride falls in its swing), touched at `touch` phases with
    /// `touch_n`: the clean report and the touched one.
    fn touched_before_the_first_counted_stride(
        touch: std::ops::Range<f64>,
        touch_n: f64,
    ) -> [FootReport; 2] {
        let stance = |phase: f64| {
            if !(0.175..0.5).contains(&phase) {
                600.0
            } else {
                0.0
            }
        };
        let touched = |phase: f64| {
            if touch.contains(&phase) {
                touch_n
            } else {
                stance(phase)
            }
        };
        [foot_report(6, stance), foot_report(6, touched)]
    }

    #[test]
    fn regression_a_scuff_before_the_first_counted_stride_is_no_stride() {
        // Unsupported, without a foot lifter, the left foot's first contact after its
        // first stride was a 0.33 s drag of 0.15 BW in swing; with no counted stride to
        // merge it into, it was counted as one, and the loading peak's mean fell to 0.92
        // of the belt's load while every stance reached 1.21-1.24. Here a drag of 110 N
        // (0.15 BW) from 23 % to 42 % (0.33 s), on gait_treadmill (30 % support: a scuff
        // under 257 N):
        let [clean, dragged] = touched_before_the_first_counted_stride(0.23..0.42, 110.0);
        assert_eq!(clean.scuffs, 0);
        assert_eq!(dragged.strides, clean.strides, "{dragged:?}");
        assert_eq!(dragged.scuffs, clean.strides + 1, "{dragged:?}");
        assert_eq!(dragged.peak_grf_bw, clean.peak_grf_bw);
        assert!(dragged.per_stride.iter().all(|s| s.peak_grf_bw > 0.8));
        let gap = (dragged.stance_fraction.mean - clean.stance_fraction.mean).abs();
        assert!(gap < 1e-9, "{gap}");
    }

    #[test]
    fn a_brief_heavy_touch_before_the_first_counted_stride_is_no_stride() {
        // A toe's 53 ms stamp of 600 N: over the load, under a quarter of the reference's
        // stance.
        let [clean, touched] = touched_before_the_first_counted_stride(0.40..0.43, 600.0);
        assert_eq!(touched.strides, clean.strides, "{touched:?}");
        assert_eq!(touched.scuffs, clean.strides + 1, "{touched:?}");
        assert_eq!(touched.peak_grf_bw, clean.peak_grf_bw);
    }
}
