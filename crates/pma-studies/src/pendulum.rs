//! The Wartenberg pendulum test, the clinic's standard measure of knee spasticity: the
//! patient sits with the thigh supported horizontally, the examiner lifts the shank to
//! full extension and lets it fall. A spastic quadriceps brakes the first swing.
//!
//! The exoskeleton's hip range (-20..50 deg) does not reach a seated 90 deg, so the fixed
//! pelvis is pitched back until the thigh lies horizontal at the held hip angle; the
//! exoskeleton's 80 deg knee stop and its muscles' stroke would stop the swing, so the
//! knee's upper limit is opened to [`KNEE_LIMIT_DEG`] and the muscles are vented and
//! unhooked (the limb swings alone, with the joint's damping and the patient model).
//!
//! Indices (Leslie et al. 1992; Bajd & Vodovnik 1984): with the knee's start angle
//! `q0`, first flexion peak `q1` and resting angle `qr`, the first-swing excursion is
//! `A1 = q1 - q0`, the relaxation index `R2 = A1 / (qr - q0)` (healthy adults 1.678 +-
//! 0.090, Kim et al. 1996) and `R2n = R2 / 1.6` (about 1 or more when healthy).
use pma_control::ControllerKind;
use pma_leg::LegError;
use pma_leg::LegSim;
use pma_leg::LoadedScenario;
use pma_leg::Mount;
use pma_leg::SupervisedLeg;
use pma_leg::{LegOutput, PerLeg, Vented};
use pma_loop::{LoopSettings, Period, Recorder, Schema, Signals};

/// The knee's upper limit during the test (deg): the shank may swing past vertical as far
/// as soft tissue allows.
pub const KNEE_LIMIT_DEG: f64 = 160.0;
/// Knee angle at which the shank hangs, the thigh horizontal (deg).
pub const HANGING_KNEE_DEG: f64 = 90.0;
/// Smallest fall from release to hanging the test accepts (deg): `R2` divides by it.
pub const MIN_DROP_DEG: f64 = 10.0;
/// A flexion peak counts as an oscillation if it exceeds the resting angle by this (deg).
pub const OSCILLATION_DEG: f64 = 1.0;
/// The resting angle is the mean over the run's last this many seconds (s).
pub const REST_WINDOW_S: f64 = 1.0;
/// The knee has settled if it moved at most this much over the last second (deg).
pub const SETTLED_DEG: f64 = 2.0;
/// Longest test (s): a swing settles within about 10 s, and the trace is kept in memory.
pub const MAX_DURATION_S: f64 = 600.0;

/// How the leg is held before release.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PendulumSetup {
    /// Hip flexion, held throughout (rad); the pelvis is pitched so the thigh is horizontal.
    pub hip_rad: f64,
    /// Knee flexion at release (rad); 0 is full extension.
    pub knee_rad: f64,
}

impl Default for PendulumSetup {
    fn default() -> Self {
        Self {
            hip_rad: 0.0,
            knee_rad: 0.0,
        }
    }
}

/// What a pendulum test measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PendulumReport {
    /// Scenario name.
    pub scenario: String,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Held hip flexion (deg).
    pub hip_deg: f64,
    /// Pelvis pitch that puts the thigh horizontal (deg).
    pub pelvis_pitch_deg: f64,
    /// Knee at release (deg).
    pub knee_start_deg: f64,
    /// First flexion peak (deg).
    pub first_peak_deg: f64,
    /// First-swing excursion `A1` (deg).
    pub first_swing_excursion_deg: f64,
    /// Resting angle: the mean over the last second (deg).
    pub knee_rest_deg: f64,
    /// Knee range over the last second (deg): how far from settled the run ended.
    pub last_second_range_deg: f64,
    /// Whether the knee came to rest: it moved at most [`SETTLED_DEG`] over the last second.
    pub settled: bool,
    /// Relaxation index `R2 = A1 / (rest - start)`; `None` if the knee has not settled
    /// (there is no resting angle to divide by).
    pub r2: Option<f64>,
    /// `R2 / 1.6`; `None` if the knee has not settled.
    pub r2n: Option<f64>,
    /// Flexion peaks more than 1 deg beyond the resting angle.
    pub oscillations: usize,
    /// Fastest knee speed (deg/s).
    pub peak_knee_velocity_deg_s: f64,
    /// Largest |knee torque of the patient| (N m).
    pub peak_patient_torque_nm: f64,
    /// Largest |E - E0| of the leg's kinetic + gravitational energy, over the swing energy
    /// `E0 - E_hanging`: a conservation check, about 0 only without joint damping and
    /// patient (damping and a reflex dissipate energy, a passive moment stores some).
    pub energy_change_relative: f64,
    /// Whether every state stayed finite.
    pub finite: bool,
}

/// One period of the pendulum test as logs show it: the leg swinging on its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PendulumSample {
    /// Time (s).
    pub t_s: f64,
    /// Joint angles (rad): the hip held, the knee swinging.
    pub angle_rad: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// The patient's torques by part (N m, flexion positive).
    pub patient: pma_leg::PatientTorques,
    /// The knee's joint damping torque (N m).
    pub knee_damping_nm: f64,
}

impl PendulumSample {
    /// The test's view of one period; `knee_damping_nm_s_per_rad` is the joint's damping.
    pub fn of(
        p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>,
        knee_damping_nm_s_per_rad: f64,
    ) -> Self {
        let s = &p.truth.legs[0];
        Self {
            t_s: p.t_s,
            angle_rad: s.angle_rad,
            velocity_rad_s: s.velocity_rad_s,
            patient: s.patient,
            knee_damping_nm: -knee_damping_nm_s_per_rad * s.velocity_rad_s[1],
        }
    }

    /// The test's channels (after the time), as the CSV and Rerun show them.
    pub fn schema() -> Schema {
        let mut s = Schema::new();
        for j in ["hip", "knee"] {
            s.push_part("joints", j, "angle_deg", "angle (deg)")
                .push_part("joints", j, "velocity_deg_s", "velocity (deg/s)")
                .push_part(
                    "joints",
                    j,
                    "patient_torque_nm",
                    "patient torque, all parts (N m)",
                )
                .push_part(
                    "joints",
                    j,
                    "reflex_torque_nm",
                    "stretch reflex torque (N m)",
                )
                .push_part("joints", j, "spasm_torque_nm", "spasm torque (N m)")
                .push_part("joints", j, "stiffness_torque_nm", "passive moment (N m)");
        }
        s.push_part(
            "joints",
            "knee",
            "damping_torque_nm",
            "joint damping torque (N m)",
        );
        s
    }
}

impl Signals for PendulumSample {
    fn values(&self, out: &mut [f64]) {
        let total = self.patient.total();
        let per_joint = |j: usize| {
            [
                self.angle_rad[j].to_degrees(),
                self.velocity_rad_s[j].to_degrees(),
                total[j],
                self.patient.reflex_nm[j],
                self.patient.spasm_nm[j],
                self.patient.stiffness_nm[j],
            ]
        };
        out[..6].copy_from_slice(&per_joint(0));
        out[6..12].copy_from_slice(&per_joint(1));
        out[12] = self.knee_damping_nm;
    }
}

/// The knee's trajectory, pre-sized for the run.
struct Trace {
    t_s: Vec<f64>,
    knee: Vec<f64>,
    knee_velocity: Vec<f64>,
    energy: Vec<f64>,
    patient_peak: f64,
    finite: bool,
}

impl Recorder<SupervisedLeg, PerLeg<LegOutput>> for Trace {
    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        let s = &p.truth.legs[0];
        self.t_s.push(p.t_s);
        self.knee.push(s.angle_rad[1]);
        self.knee_velocity.push(s.velocity_rad_s[1]);
        self.energy.push(p.backend.exo().energy());
        self.patient_peak = self.patient_peak.max(s.patient.total()[1].abs());
        self.finite &= s
            .angle_rad
            .iter()
            .chain(&s.velocity_rad_s)
            .all(|v| v.is_finite());
    }
}

/// The seated test's leg: pelvis pitched, knee limit opened, muscles vented and unhooked,
/// thigh held, knee at its release angle.
pub fn seated(loaded: &LoadedScenario, setup: PendulumSetup) -> Result<LegSim, LegError> {
    for (name, v) in [("hip", setup.hip_rad), ("knee", setup.knee_rad)] {
        if !v.is_finite() {
            return Err(LegError::from(pma_model::Invalid::new(
                format!("{name} angle (rad)"),
                v,
                "must be finite",
            )));
        }
    }
    // The patient's effort follows the gait's reference: there is none to follow here. A
    // spasm during the swing would spoil the test (the clinic repeats it). The reflex and
    // the passive joint moments stay: they are what the test measures.
    let mut loaded = loaded.clone();
    for joint in [
        &mut loaded.scenario.patient.hip,
        &mut loaded.scenario.patient.knee,
    ] {
        joint.effort = None;
        joint.spasms = None;
    }
    let loaded = &loaded;
    let mount = Mount {
        pelvis_pitch_rad: std::f64::consts::FRAC_PI_2 - setup.hip_rad,
        knee_limits_rad: None,
    };
    // The URDF's own knee lower limit stays; only the stop at 80 deg goes.
    let probe = LegSim::mounted(loaded, &ControllerKind::Pid.default_config(), mount)?;
    let [[hip_lo, hip_hi], [knee_lo, _]] = probe.exo().limits_rad(0);
    let knee_hi = KNEE_LIMIT_DEG.to_radians();
    if !(hip_lo..=hip_hi).contains(&setup.hip_rad) {
        return Err(LegError::from(pma_model::Invalid::new(
            "hip angle (deg)",
            as_given_deg(setup.hip_rad),
            "must lie within the URDF's hip limits",
        )));
    }
    if !(knee_lo..=HANGING_KNEE_DEG.to_radians() - MIN_DROP_DEG.to_radians())
        .contains(&setup.knee_rad)
    {
        return Err(LegError::from(pma_model::Invalid::new("knee angle (deg)", as_given_deg(setup.knee_rad), "must lie between the URDF's lower knee limit and 80 deg: the shank hangs at 90 deg and must fall at least 10 deg")));
    }
    let mount = Mount {
        knee_limits_rad: Some([knee_lo, knee_hi]),
        ..mount
    };
    let mut sim = LegSim::mounted(loaded, &ControllerKind::Pid.default_config(), mount)?;
    sim.release_muscles()?;
    sim.plant_mut().exo_mut().hold(0, 0, setup.hip_rad);
    sim.set_state([setup.hip_rad, setup.knee_rad], [0.0, 0.0]);
    Ok(sim)
}

/// An angle in degrees as the caller gave it before it became radians: the round trip's
/// last-bit error removed (`500` deg comes back as 500.00000000000006), 12 significant
/// digits kept.
fn as_given_deg(rad: f64) -> f64 {
    format!("{:.11e}", rad.to_degrees())
        .parse()
        .unwrap_or(rad.to_degrees())
}

/// Runs the test on a leg from [`seated`] with the same `setup`, `recorder` observing
/// every period.
pub fn run<R: Recorder<SupervisedLeg, PerLeg<LegOutput>>>(
    mut sim: LegSim,
    setup: PendulumSetup,
    settings: &LoopSettings,
    recorder: &mut R,
) -> Result<PendulumReport, LegError> {
    if settings.duration_s() > MAX_DURATION_S {
        return Err(LegError::from(pma_model::Invalid::new(
            "duration (s)",
            settings.duration_s(),
            "must be at most 600 s for a pendulum test (it settles within about 10 s)",
        )));
    }
    let n = settings.periods(sim.scenario().period_s)? as usize;
    let mut trace = Trace {
        t_s: Vec::with_capacity(n),
        knee: Vec::with_capacity(n),
        knee_velocity: Vec::with_capacity(n),
        energy: Vec::with_capacity(n),
        patient_peak: 0.0,
        finite: true,
    };
    let e0 = sim.exo().energy();
    let pitch = std::f64::consts::FRAC_PI_2 - setup.hip_rad;
    // The shank hangs when its absolute angle (hip + pitch - knee) is zero.
    let hanging = [setup.hip_rad, setup.hip_rad + pitch];
    let e_hanging = sim.exo().inertia().energy(hanging, [0.0, 0.0]);
    let mut task = Vented::pose([setup.hip_rad, setup.knee_rad]);
    let outcome = sim.run_task(&mut task, &mut (&mut trace, recorder), settings)?;
    let ran_s = outcome.periods as f64 * sim.scenario().period_s;
    let swung = trace
        .knee_velocity
        .windows(2)
        .any(|w| w[0] > 0.0 && w[1] <= 0.0);
    if !swung && trace.finite {
        return Err(LegError::from(pma_model::Invalid::new(
            "duration (s)",
            ran_s,
            "is too short: the knee reached no flexion peak (run at least 2 s)",
        )));
    }
    Ok(indices(
        &sim.scenario().name,
        setup,
        pitch,
        &trace,
        e0,
        e_hanging,
        ran_s,
    ))
}

fn indices(
    scenario: &str,
    setup: PendulumSetup,
    pitch: f64,
    tr: &Trace,
    e0: f64,
    e_hanging: f64,
    ran_s: f64,
) -> PendulumReport {
    let q0 = setup.knee_rad;
    let t_end = tr.t_s.last().copied().unwrap_or(0.0);
    let last: Vec<f64> = tr
        .t_s
        .iter()
        .zip(&tr.knee)
        .filter(|(t, _)| **t > t_end - REST_WINDOW_S)
        .map(|(_, q)| *q)
        .collect();
    let rest = if last.is_empty() {
        f64::NAN
    } else {
        last.iter().sum::<f64>() / last.len() as f64
    };
    let range = last.iter().fold(f64::NEG_INFINITY, |m, q| m.max(*q))
        - last.iter().fold(f64::INFINITY, |m, q| m.min(*q));
    // Flexion peaks: the knee's velocity turns from positive to non-positive.
    let peaks: Vec<f64> = tr
        .knee_velocity
        .windows(2)
        .zip(tr.knee.iter().skip(1))
        .filter(|(w, _)| w[0] > 0.0 && w[1] <= 0.0)
        .map(|(_, q)| *q)
        .collect();
    let first_peak = peaks.first().copied().unwrap_or(f64::NAN);
    let a1 = first_peak - q0;
    let r2 = a1 / (rest - q0);
    let settled = range.to_degrees() <= SETTLED_DEG;
    let energy_change =
        tr.energy.iter().fold(0.0f64, |m, e| m.max((e - e0).abs())) / (e0 - e_hanging);
    PendulumReport {
        scenario: scenario.to_owned(),
        duration_s: ran_s,
        hip_deg: setup.hip_rad.to_degrees(),
        pelvis_pitch_deg: pitch.to_degrees(),
        knee_start_deg: q0.to_degrees(),
        first_peak_deg: first_peak.to_degrees(),
        first_swing_excursion_deg: a1.to_degrees(),
        knee_rest_deg: rest.to_degrees(),
        last_second_range_deg: range.to_degrees(),
        settled,
        r2: settled.then_some(r2),
        r2n: settled.then_some(r2 / 1.6),
        oscillations: peaks
            .iter()
            .filter(|q| (**q - rest).to_degrees() > OSCILLATION_DEG)
            .count(),
        peak_knee_velocity_deg_s: tr
            .knee_velocity
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .to_degrees(),
        peak_patient_torque_nm: tr.patient_peak,
        energy_change_relative: energy_change,
        finite: tr.finite,
    }
}
