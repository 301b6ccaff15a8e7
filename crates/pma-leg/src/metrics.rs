//! The leg's figures: tracking after the first stride, pressures, slack time, the common
//! mode's drift and valve activity, accumulated by a [`Recorder`] without allocation.
use crate::control::LegOutput;
use crate::exoskeleton::JOINT_NAMES;
use crate::legs::PerLeg;
use crate::plant::{leg_label, LegPlant, LegState, SupervisedLeg, TrainerState};
use crate::safety::{PatientMetrics, PatientReport, SafetyReport, SpasmReport};

/// `map`'s keys as outputs name them on leg `leg` of a trainer of `legs` legs.
fn labelled<V>(
    legs: usize,
    leg: usize,
    map: BTreeMap<String, V>,
) -> impl Iterator<Item = (String, V)> {
    map.into_iter()
        .map(move |(k, v)| (leg_label(legs, leg, &k), v))
}
use pma_loop::{End, Period, Recorder, Start};
use std::collections::BTreeMap;

impl LegReport {
    /// The run's report from every leg's metrics (one `LegMetrics` and one
    /// `PatientMetrics` per leg, in leg order, each patient's with the run's end): one leg's
    /// figures keyed as in the air (`hip`, `hip_flexor`), two legs' by side (`right/hip`).
    pub fn of_legs<'a>(
        scenario: &str,
        duration_s: f64,
        wall_s: f64,
        muscle_names: &[String],
        metrics: impl ExactSizeIterator<Item = &'a LegMetrics>,
        patients: impl Iterator<Item = (&'a PatientMetrics, f64)>,
    ) -> LegReport {
        let legs = metrics.len();
        let mut out: Option<LegReport> = None;
        let mut sums = (0.0, 0.0, 0.0);
        for (leg, (m, (p, end_s))) in metrics.zip(patients).enumerate() {
            let r = m.report(scenario, muscle_names, duration_s, wall_s);
            sums.0 += r.cocontraction_pa.start;
            sums.1 += r.cocontraction_pa.end;
            sums.2 += r.command_variation_bar_per_s;
            let all = out.get_or_insert_with(|| LegReport {
                joints: BTreeMap::new(),
                muscles: BTreeMap::new(),
                ..r.clone()
            });
            all.joints.extend(labelled(legs, leg, r.joints));
            all.muscles.extend(labelled(legs, leg, r.muscles));
            all.finite &= r.finite;
            all.patient
                .joints
                .extend(labelled(legs, leg, p.patient().joints));
            all.spasms.extend(p.spasms(end_s).into_iter().map(|mut s| {
                s.joint = leg_label(legs, leg, &s.joint);
                s
            }));
            let safety = p.safety(muscle_names);
            all.safety.joints.extend(labelled(legs, leg, safety.joints));
            all.safety
                .muscles
                .extend(labelled(legs, leg, safety.muscles));
        }
        let mut report = out.unwrap_or_else(|| {
            LegMetrics::new(1.0, 1.0).report(scenario, muscle_names, duration_s, wall_s)
        });
        let n = legs.max(1) as f64;
        report.cocontraction_pa = CoContractionStats {
            start: sums.0 / n,
            end: sums.1 / n,
        };
        report.command_variation_bar_per_s = sums.2 / n;
        report.spasms.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        report
    }

    /// A joint's RMS tracking error (deg) over the legs (`hip` or `knee`): the mean of
    /// every leg's.
    pub fn joint_rms_deg(&self, joint: &str) -> f64 {
        let (sum, n) = self
            .joints
            .iter()
            .filter(|(k, _)| *k == joint || k.ends_with(&format!("/{joint}")))
            .fold((0.0, 0), |(s, n), (_, v)| (s + v.rms_deg, n + 1));
        if n > 0 {
            sum / f64::from(n)
        } else {
            f64::NAN
        }
    }
}

/// One leg's view of the loop's start.
#[derive(Debug, Clone, Copy)]
pub struct LegStart<'a> {
    /// Time of the start (s).
    pub t_s: f64,
    /// The leg's state.
    pub state: &'a LegState,
    /// The pressures the leg's valves held at rest (Pa).
    pub resting: &'a [f64; 4],
    /// The whole trainer's state (the treadmill's, the other legs').
    pub trainer: &'a TrainerState,
}

/// One leg's view of one loop period.
#[derive(Clone, Copy)]
pub struct LegPeriod<'a> {
    /// The leg (0 right, 1 left).
    pub leg: usize,
    /// Time of the reading (s).
    pub t_s: f64,
    /// Time since the previous reading (s).
    pub dt_s: f64,
    /// The leg's state at the reading.
    pub state: &'a LegState,
    /// What the leg's controllers made of it.
    pub output: &'a LegOutput,
    /// The pressures held over the period that just ended (Pa).
    pub held: &'a [f64; 4],
    /// The pressures written for the next period (Pa).
    pub written: &'a [f64; 4],
    /// The whole trainer's state (the treadmill's, the other legs').
    pub trainer: &'a TrainerState,
    /// The plant.
    pub plant: &'a LegPlant,
}

/// A recorder of one leg: the leg's figures are written once, for one leg, and run on
/// each leg of a trainer through [`OnLeg`].
pub trait LegRecorder {
    /// The run has started.
    fn start(&mut self, start: &LegStart<'_>) {
        let _ = start;
    }
    /// One period.
    fn record(&mut self, period: &LegPeriod<'_>);
}

/// Runs a one-leg recorder on leg `leg` of the trainer's loop.
#[derive(Debug, Clone)]
pub struct OnLeg<R> {
    /// The leg it follows.
    pub leg: usize,
    /// The recorder.
    pub inner: R,
}

impl<R> OnLeg<R> {
    /// `inner` on leg `leg`.
    pub fn new(leg: usize, inner: R) -> Self {
        Self { leg, inner }
    }
}

impl<R: LegRecorder> Recorder<SupervisedLeg, PerLeg<LegOutput>> for OnLeg<R> {
    fn start(&mut self, s: &Start<'_, SupervisedLeg>) {
        let (Some(state), Some(resting)) = (s.truth.legs.get(self.leg), s.resting.get(self.leg))
        else {
            return;
        };
        self.inner.start(&LegStart {
            t_s: s.t_s,
            state,
            resting,
            trainer: s.truth,
        });
    }

    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        let leg = self.leg;
        let (Some(state), Some(output), Some(held), Some(written)) = (
            p.truth.legs.get(leg),
            p.output.get(leg),
            p.held.get(leg),
            p.written.get(leg),
        ) else {
            return;
        };
        self.inner.record(&LegPeriod {
            leg,
            t_s: p.t_s,
            dt_s: p.dt_s,
            state,
            output,
            held,
            written,
            trainer: p.truth,
            plant: p.backend.inner(),
        });
    }

    fn end(&mut self, _: &End<<SupervisedLeg as pma_loop::Backend>::Error>, _: f64) {}
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
    pub joints: BTreeMap<String, JointStats>,
    /// Per muscle.
    pub muscles: BTreeMap<String, MuscleStats>,
    /// Common mode.
    pub cocontraction_pa: CoContractionStats,
    /// Mean total variation of the four pressure commands per second (bar/s): valve
    /// activity, where chattering shows.
    pub command_variation_bar_per_s: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
    /// Simulated seconds per wall-clock second.
    pub real_time_factor: f64,
    /// Whether the run was stopped early (SIGINT, SIGTERM).
    pub interrupted: bool,
    /// The patient's torques.
    pub patient: PatientReport,
    /// Each spasm of the run and what it did.
    pub spasms: Vec<SpasmReport>,
    /// Joint limits, muscle forces, valve saturation.
    pub safety: SafetyReport,
    /// Stance and swing, ground reaction forces, slip and heel strikes, on a treadmill.
    pub treadmill: Option<crate::stance::TreadmillReport>,
    /// What the device did to the patient and the patient's own gait, leg by leg.
    pub cooperation: Vec<crate::cooperative::CooperationReport>,
    /// The gait's clock where it follows the legs' lead (`phase_sync_per_s`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_sync: Option<crate::phase_sync::PhaseSyncReport>,
    /// On a treadmill: whether the patient walked, and if not why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub walking: Option<crate::verdict::WalkingVerdict>,
}

/// Accumulates the [`LegReport`] figures period by period.
#[derive(Debug, Clone)]
pub struct LegMetrics {
    stride_s: f64,
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
    previous: [f64; 4],
    finite: bool,
    t_s: f64,
}

impl LegMetrics {
    /// Figures for a gait of `stride_s` at `period_s` (the ring buffer is sized here).
    pub fn new(stride_s: f64, period_s: f64) -> Self {
        Self {
            stride_s,
            n: [0; 2],
            sum_sq: [0.0; 2],
            max_abs: [0.0; 2],
            p_min: [f64::INFINITY; 4],
            p_max: [f64::NEG_INFINITY; 4],
            slack_s: [0.0; 4],
            cm_start: (0.0, 0),
            cm_ring: vec![0.0; (stride_s / period_s).round().max(1.0) as usize],
            cm_next: 0,
            cm_filled: false,
            variation: 0.0,
            previous: [0.0; 4],
            finite: true,
            t_s: 0.0,
        }
    }

    fn push_tracking(&mut self, reference_rad: [f64; 2], angle_rad: [f64; 2]) {
        for j in 0..2 {
            let e = (reference_rad[j] - angle_rad[j]).to_degrees();
            self.n[j] += 1;
            self.sum_sq[j] += e * e;
            self.max_abs[j] = self.max_abs[j].max(e.abs());
        }
    }

    fn push_common_mode(&mut self, t_s: f64, pressure_pa: &[f64; 4]) {
        let cm = pressure_pa.iter().sum::<f64>() / 4.0;
        if t_s > self.stride_s && t_s <= 2.0 * self.stride_s {
            self.cm_start.0 += cm;
            self.cm_start.1 += 1;
        }
        if !self.cm_ring.is_empty() {
            self.cm_ring[self.cm_next] = cm;
            self.cm_next = (self.cm_next + 1) % self.cm_ring.len();
            self.cm_filled |= self.cm_next == 0;
        }
    }

    /// The report of the run so far.
    pub fn report(
        &self,
        scenario: &str,
        muscle_names: &[String],
        duration_s: f64,
        wall_s: f64,
    ) -> LegReport {
        let joints = JOINT_NAMES
            .iter()
            .enumerate()
            .map(|(j, n)| {
                let stats = if self.n[j] > 0 {
                    JointStats {
                        rms_deg: (self.sum_sq[j] / self.n[j] as f64).sqrt(),
                        max_deg: self.max_abs[j],
                    }
                } else {
                    JointStats {
                        rms_deg: f64::NAN,
                        max_deg: f64::NAN,
                    }
                };
                ((*n).to_owned(), stats)
            })
            .collect();
        let muscles = muscle_names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                (
                    name.clone(),
                    MuscleStats {
                        p_min_pa: self.p_min[i],
                        p_max_pa: self.p_max[i],
                        slack_s: self.slack_s[i],
                    },
                )
            })
            .collect();
        let last = if self.cm_filled {
            &self.cm_ring[..]
        } else {
            &self.cm_ring[..self.cm_next]
        };
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        LegReport {
            scenario: scenario.to_owned(),
            duration_s,
            joints,
            muscles,
            cocontraction_pa: CoContractionStats {
                start: if self.cm_start.1 > 0 {
                    self.cm_start.0 / self.cm_start.1 as f64
                } else {
                    f64::NAN
                },
                end: mean(last),
            },
            command_variation_bar_per_s: self.variation / self.t_s.max(1e-12) / 1e5,
            finite: self.finite,
            real_time_factor: duration_s / wall_s.max(1e-12),
            interrupted: false,
            patient: PatientReport::default(),
            spasms: Vec::new(),
            safety: SafetyReport::default(),
            treadmill: None,
            cooperation: Vec::new(),
            phase_sync: None,
            walking: None,
        }
    }
}

impl LegRecorder for LegMetrics {
    fn start(&mut self, s: &LegStart<'_>) {
        self.previous = *s.resting;
        self.t_s = s.t_s;
    }

    /// The figures pair the state at the reading with the commands held over the period
    /// that led to it.
    fn record(&mut self, p: &LegPeriod<'_>) {
        let held = *p.held;
        self.variation += held
            .iter()
            .zip(self.previous)
            .map(|(u, prev)| (u - prev).abs())
            .sum::<f64>()
            / 4.0;
        self.previous = held;
        self.t_s = p.t_s;
        let s = p.state;
        self.finite &= s.angle_rad.iter().chain(&held).all(|v| v.is_finite());
        if p.t_s > self.stride_s {
            self.push_tracking(p.output.reference_rad, s.angle_rad);
        }
        for i in 0..4 {
            self.p_min[i] = self.p_min[i].min(s.pressure_pa[i]);
            self.p_max[i] = self.p_max[i].max(s.pressure_pa[i]);
            self.slack_s[i] += s.slack_s[i];
        }
        self.push_common_mode(p.t_s, &s.pressure_pa);
    }
}
