//! Perturbation tests of a joint's realised impedance on the leg in the air: a load held
//! each way for the static stiffness ([`probe_stiffness`]), and a sinusoidal load for the
//! dynamic stiffness at a frequency ([`probe_frequency`]).
use crate::base::LegError;
use crate::control::ControlMode;
use serde::Serialize;

/// A small-perturbation test of one joint's realised stiffness.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StiffnessProbe {
    /// The joint (`hip`, `knee`).
    pub joint: &'static str,
    /// Stiffness asked (N m/rad).
    pub set_nm_per_rad: f64,
    /// Stiffness measured: the load over the deflection (N m/rad); NaN if the joint did
    /// not move (`held_by_friction`).
    pub realised_nm_per_rad: f64,
    /// `realised / set - 1` (NaN if the joint did not move).
    pub error: f64,
    /// Whether the joint's friction held the load: the deflection under a tenth of what
    /// the set point gives, no stiffness measured.
    pub held_by_friction: bool,
    /// Load hung each way (N m).
    pub load_nm: f64,
    /// Deflection between the two loads (deg).
    pub deflection_deg: f64,
}

/// Where a perturbation test holds the first leg of an in-air scenario, and how.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeAt {
    /// Impedance (co-contraction) or admittance.
    pub mode: ControlMode,
    /// The joint loaded (0 hip, 1 knee).
    pub joint: usize,
    /// Its stiffness set point (N m/rad); the other joint at its default.
    pub stiffness_nm_per_rad: f64,
    /// The pose held (rad, hip and knee flexion).
    pub pose_rad: [f64; 2],
}

/// Deflection the perturbation aims at (rad): a degree each way, small against the gait's
/// range and large against the valves' pressure resolution.
const PROBE_DEFLECTION_RAD: f64 = 0.017_453_292_519_943_295;

/// The first leg of an in-air scenario held as `at` says: what every perturbation test
/// starts from, with the joint's name.
fn held_in_mode(
    loaded: &crate::scenario::LoadedScenario,
    at: &ProbeAt,
) -> Result<(&'static str, crate::sim::LegSim), LegError> {
    let ProbeAt {
        mode,
        joint,
        stiffness_nm_per_rad: stiffness,
        pose_rad,
    } = *at;
    let name = crate::base::JOINT_NAMES
        .get(joint)
        .copied()
        .ok_or_else(|| {
            crate::base::invalid("joint", joint as f64, "must be 0 (hip) or 1 (knee)")
        })?;
    if loaded.scenario.treadmill.is_some() {
        return Err(LegError::Unreachable {
            name: "treadmill".into(),
            value: f64::NAN,
            message: format!(
                "the perturbation test holds a leg in the air, and scenario `{}` stands on a treadmill",
                loaded.scenario.name
            ),
        });
    }
    if !matches!(mode, ControlMode::Impedance | ControlMode::Admittance) {
        return Err(LegError::Unsupported {
            name: "mode".into(),
            value: mode.to_string(),
            message: "the perturbation test runs impedance or admittance mode, the modes with a stiffness set point".into(),
        });
    }
    let mut loaded = loaded.clone();
    let control = &mut loaded.scenario.control;
    control.mode = mode;
    let set = if joint == 0 {
        &mut control.impedance.hip
    } else {
        &mut control.impedance.knee
    };
    set.stiffness_nm_per_rad = Some(stiffness);
    let mut sim = crate::sim::LegSim::new(&loaded)?;
    sim.hold_pose(pose_rad);
    sim.set_state(pose_rad, [0.0; 2]);
    Ok((name, sim))
}

/// Holds the first leg of an in-air scenario as `at` says (impedance by co-contraction, or
/// admittance through the muscles' controllers), and hangs a load of the set stiffness
/// times a degree on the joint, first flexing, then extending, each for `settle_s`: the
/// realised stiffness is twice the load over the deflection between the two steady poses.
pub fn probe_stiffness(
    loaded: &crate::scenario::LoadedScenario,
    at: &ProbeAt,
    settle_s: f64,
) -> Result<StiffnessProbe, LegError> {
    let (name, mut sim) = held_in_mode(loaded, at)?;
    let (joint, stiffness) = (at.joint, at.stiffness_nm_per_rad);
    let load_nm = stiffness * PROBE_DEFLECTION_RAD;
    let mut settled = |sign: f64| -> Result<f64, LegError> {
        let mut torque = [0.0; 2];
        torque[joint] = sign * load_nm;
        sim.plant_mut().set_external_torque(0, torque);
        sim.run(settle_s, &mut ())?;
        Ok(sim.exo().angles(0)[joint])
    };
    let flexed = settled(1.0)?;
    let extended = settled(-1.0)?;
    let deflection = flexed - extended;
    let held_by_friction = deflection < 0.1 * 2.0 * PROBE_DEFLECTION_RAD;
    let realised = if held_by_friction {
        f64::NAN
    } else {
        2.0 * load_nm / deflection
    };
    Ok(StiffnessProbe {
        joint: name,
        set_nm_per_rad: stiffness,
        realised_nm_per_rad: realised,
        error: realised / stiffness - 1.0,
        held_by_friction,
        load_nm,
        deflection_deg: deflection.to_degrees(),
    })
}

/// A frequency-response test of one joint's realised impedance: the dynamic stiffness
/// `Z = T / x` under a sinusoidal load `T`, as magnitude and phase.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrequencyProbe {
    /// The joint (`hip`, `knee`).
    pub joint: &'static str,
    /// The load's frequency (Hz).
    pub frequency_hz: f64,
    /// Stiffness asked (N m/rad).
    pub set_nm_per_rad: f64,
    /// The load's amplitude (N m): the set stiffness times a degree.
    pub load_nm: f64,
    /// `|Z|` measured (N m/rad).
    pub magnitude_nm_per_rad: f64,
    /// Phase of `Z` measured (deg): how far the load leads the deflection.
    pub phase_deg: f64,
    /// Admittance mode: `|Z|` of its law with an ideal servo and the limb's own inertia,
    /// `(K + i w D)(1 + i w tau_f) - w^2 I_limb` (N m/rad); NaN in impedance mode, whose
    /// spring is the muscles' and whose inertia is the whole leg's.
    pub model_magnitude_nm_per_rad: f64,
    /// Its phase (deg).
    pub model_phase_deg: f64,
    /// `measured / model - 1` of the magnitudes (NaN without a model).
    pub magnitude_error: f64,
}

/// Frequencies a frequency-response test takes (Hz): slow enough for the leg's dynamics
/// to matter little in the gait's band, at most ten times a stride's rate.
pub const PROBE_FREQUENCY_RANGE_HZ: [f64; 2] = [0.05, 10.0];

/// Cycles a frequency-response test lets pass before it measures, and measures over.
const SETTLE_CYCLES: f64 = 4.0;
const MEASURED_CYCLES: f64 = 4.0;
/// Least settling (s): the co-contraction spring's time constant is about 1.6 s.
const SETTLE_MIN_S: f64 = 5.0;

/// The joint's angle over a test's measured window.
struct JointTrace {
    joint: usize,
    from_s: f64,
    t_s: Vec<f64>,
    angle_rad: Vec<f64>,
}

impl pma_loop::Recorder<crate::plant::SupervisedLeg, crate::base::PerLeg<crate::control::LegOutput>>
    for JointTrace
{
    fn record(
        &mut self,
        p: &pma_loop::Period<
            '_,
            crate::plant::SupervisedLeg,
            crate::base::PerLeg<crate::control::LegOutput>,
        >,
    ) {
        if p.t_s >= self.from_s {
            self.t_s.push(p.t_s);
            self.angle_rad.push(p.truth.legs[0].angle_rad[self.joint]);
        }
    }
}

impl JointTrace {
    /// The response's phasor at `omega` (rad/s): `(a, b)` of `a sin(w t) + b cos(w t)`,
    /// projected over the window's whole cycles, the mean removed.
    fn phasor(&self, omega: f64) -> (f64, f64) {
        let n = self.angle_rad.len() as f64;
        let mean = self.angle_rad.iter().sum::<f64>() / n;
        let (mut a, mut b) = (0.0, 0.0);
        for (t, x) in self.t_s.iter().zip(&self.angle_rad) {
            a += (x - mean) * (omega * t).sin();
            b += (x - mean) * (omega * t).cos();
        }
        (2.0 * a / n, 2.0 * b / n)
    }
}

/// Holds the first leg of an in-air scenario as `at` says and loads the joint with the set
/// stiffness times a degree, sinusoidally at `frequency_hz`: after four cycles (and at least 5 s) settle, the joint's response
/// over four more gives the dynamic stiffness, against admittance mode's model.
pub fn probe_frequency(
    loaded: &crate::scenario::LoadedScenario,
    at: &ProbeAt,
    frequency_hz: f64,
) -> Result<FrequencyProbe, LegError> {
    let (joint, stiffness, pose_rad) = (at.joint, at.stiffness_nm_per_rad, at.pose_rad);
    let [lo, hi] = PROBE_FREQUENCY_RANGE_HZ;
    pma_model::error::within(
        "frequency_hz",
        frequency_hz,
        lo,
        hi,
        "must be 0.05 to 10 Hz (a frequency-response test's load)",
    )?;
    let (name, mut sim) = held_in_mode(loaded, at)?;
    let load_nm = stiffness * PROBE_DEFLECTION_RAD;
    sim.plant_mut()
        .set_external_wave(Some(crate::plant::ExternalWave {
            leg: 0,
            joint,
            amplitude_nm: load_nm,
            frequency_hz,
        }));
    let settle_s = (SETTLE_CYCLES / frequency_hz).max(SETTLE_MIN_S);
    let measured_s = MEASURED_CYCLES / frequency_hz;
    let periods = (measured_s / loaded.scenario.period_s).ceil() as usize + 1;
    let mut trace = JointTrace {
        joint,
        from_s: sim.time() + settle_s,
        t_s: Vec::with_capacity(periods),
        angle_rad: Vec::with_capacity(periods),
    };
    sim.run(settle_s + measured_s, &mut trace)?;
    let omega = std::f64::consts::TAU * frequency_hz;
    let (a, b) = trace.phasor(omega);
    // x = Im[(a + i b) e^(i w t)] under T = Im[load e^(i w t)]: Z = load / (a + i b).
    let response = a.hypot(b);
    let magnitude = load_nm / response;
    let phase_deg = -b.atan2(a).to_degrees();
    let (model_magnitude, model_phase_deg) = match sim.controllers().leg(0).admittance() {
        Some(adm) => {
            let k = adm.stiffness_nm_per_rad()[joint];
            let d = adm.damping_nm_s_per_rad()[joint];
            let tau = loaded.scenario.control.impedance.cuff_filter_s;
            let limb = sim.exo().inertia().limb();
            let inertia = limb_inertia(&limb, pose_rad, joint);
            // (K + i w D)(1 + i w tau) - w^2 I
            let re = k - omega * omega * d * tau - omega * omega * inertia;
            let im = omega * d + omega * k * tau;
            (re.hypot(im), im.atan2(re).to_degrees())
        }
        None => (f64::NAN, f64::NAN),
    };
    Ok(FrequencyProbe {
        joint: name,
        frequency_hz,
        set_nm_per_rad: stiffness,
        load_nm,
        magnitude_nm_per_rad: magnitude,
        phase_deg,
        model_magnitude_nm_per_rad: model_magnitude,
        model_phase_deg,
        magnitude_error: magnitude / model_magnitude - 1.0,
    })
}

/// The limb's inertia about joint `joint` at `pose_rad`, the other joint held: the
/// diagonal of its mass matrix.
fn limb_inertia(limb: &crate::body::LegInertia, pose_rad: [f64; 2], joint: usize) -> f64 {
    limb.mass_matrix(pose_rad)[joint][joint]
}
