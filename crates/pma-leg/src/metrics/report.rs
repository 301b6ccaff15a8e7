use crate::metrics::{
    CoContractionStats, JointStats, LegMetrics, MuscleStats, PatientMetrics, PatientReport,
    SafetyReport, SpasmReport,
};
use crate::plant::leg_label;
use std::collections::BTreeMap;

/// `map`'s keys as outputs name them on leg `leg` of a trainer of `legs` legs.
fn labelled<V>(
    legs: usize,
    leg: usize,
    map: BTreeMap<String, V>,
) -> impl Iterator<Item = (String, V)> {
    map.into_iter()
        .map(move |(k, v)| (leg_label(legs, leg, &k), v))
}

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
            LegMetrics::new(1.0, 1.0, 0.0).report(scenario, muscle_names, duration_s, wall_s)
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
    pub treadmill: Option<crate::metrics::TreadmillReport>,
    /// What the device did to the patient and the patient's own gait, leg by leg.
    pub cooperation: Vec<crate::metrics::CooperationReport>,
    /// The gait's clock where it follows the legs' lead (`phase_sync_per_s`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_sync: Option<crate::control::PhaseSyncReport>,
    /// On a treadmill: whether the patient walked, and if not why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub walking: Option<crate::metrics::WalkingVerdict>,
    /// The integration step the figures were computed at (`None`: not from a run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step: Option<StepReport>,
    /// The headline figures again at half the step, and how far they moved
    /// (`simulate --check-step`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub check_step: Option<StepCheckReport>,
}

/// The integration step of a run: what its figures' numerical error depends on.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepReport {
    /// Control period (s).
    pub period_s: f64,
    /// Physics steps per period.
    pub physics_substeps: u32,
    /// One physics step (s).
    pub physics_step_s: f64,
    /// Whether the muscles' damping is evaluated implicitly.
    pub implicit_muscle_damping: bool,
}

/// A joint's tracking figures at half the step and how far they moved (relative).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct JointStepCheck {
    /// RMS tracking error at half the step (deg).
    pub rms_deg: f64,
    /// Largest tracking error at half the step (deg).
    pub max_deg: f64,
    /// |RMS at half the step - RMS| / RMS.
    pub moved_rms: f64,
    /// The same for the largest error.
    pub moved_max: f64,
}

/// The run again at twice its physics substeps.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StepCheckReport {
    /// Physics steps per period of the check.
    pub physics_substeps: u32,
    /// Per joint, as in [`LegReport::joints`].
    pub joints: BTreeMap<String, JointStepCheck>,
    /// The largest relative move a converged figure may show
    /// ([`pma_loop::step::STEP_TOLERANCE`]).
    pub tolerance: f64,
    /// Whether every figure moved by at most `tolerance`.
    pub converged: bool,
}

impl StepCheckReport {
    /// `refined` (the run at `physics_substeps`) against `first`, joint by joint.
    pub fn of(first: &LegReport, refined: &LegReport, physics_substeps: u32) -> Self {
        use pma_loop::step::{converged, relative_move as rel, STEP_TOLERANCE};
        let joints: BTreeMap<String, JointStepCheck> = first
            .joints
            .iter()
            .filter_map(|(name, j)| {
                let r = refined.joints.get(name)?;
                Some((
                    name.clone(),
                    JointStepCheck {
                        rms_deg: r.rms_deg,
                        max_deg: r.max_deg,
                        moved_rms: rel(j.rms_deg, r.rms_deg),
                        moved_max: rel(j.max_deg, r.max_deg),
                    },
                ))
            })
            .collect();
        let converged = converged(joints.values().flat_map(|j| [j.moved_rms, j.moved_max]));
        Self {
            physics_substeps,
            joints,
            tolerance: STEP_TOLERANCE,
            converged,
        }
    }
}
