//! What a stride asks of the joints: the scenario's leg (on its treadmill, with its
//! patient, harness and other leg) driven along the reference by stiff joint servos instead
//! of muscles, and the torques those servos apply. It is inverse dynamics with the contact
//! forces in it: the servos supply whatever the gait, the belt and the patient need, and
//! the muscles that replace them must supply the same.
use crate::config::LoadedScenario;
use crate::error::{invalid, LegError};
use crate::gait::GaitReference;
use crate::leg::{Leg, Mount};
use crate::sim::{build_leg, build_patient};
use crate::stance::{GroundPeriod, TreadmillMetrics, TreadmillReport};

/// Stiffness of the joint servos (N m/rad): 1 deg of error for 350 N m; tracking within a
/// few tenths of a degree on the treadmill (reported as [`Demand::max_error_deg`]).
pub const SERVO_STIFFNESS_NM_PER_RAD: f64 = 20_000.0;
/// Damping of the joint servos (N m s/rad): about critical for the knee's inertia.
pub const SERVO_DAMPING_NM_S_PER_RAD: f64 = 150.0;

/// One period of the servo-driven stride.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemandSample {
    /// Time (s).
    pub t_s: f64,
    /// Joint angles (rad), hip and knee.
    pub angle_rad: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// Torque the joints need (N m, flexion positive), averaged over the period's substeps.
    pub torque_nm: [f64; 2],
}

/// The joints' demand over whole strides.
#[derive(Debug, Clone, PartialEq)]
pub struct Demand {
    /// The periods of the strides measured, after the start-up ramp and one stride.
    pub samples: Vec<DemandSample>,
    /// Largest tracking error of the servos over them (deg), hip and knee.
    pub max_error_deg: [f64; 2],
    /// The treadmill's figures of the servo-driven run (`None` in the air).
    pub treadmill: Option<TreadmillReport>,
}

impl Demand {
    /// Largest flexion and extension torque of joint `j` (N m; extension negative).
    pub fn torque_range_nm(&self, j: usize) -> [f64; 2] {
        self.samples
            .iter()
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], s| {
                [lo.min(s.torque_nm[j]), hi.max(s.torque_nm[j])]
            })
    }

    /// Largest |velocity| of joint `j` (rad/s).
    pub fn peak_speed_rad_s(&self, j: usize) -> f64 {
        self.samples
            .iter()
            .map(|s| s.velocity_rad_s[j].abs())
            .fold(0.0, f64::max)
    }
}

/// The scenario's leg driven along its gait by the joint servos for the start-up ramp and
/// `strides + 1` strides; the last `strides` are measured.
pub fn stride_demand(loaded: &LoadedScenario, strides: usize) -> Result<Demand, LegError> {
    if strides == 0 {
        return Err(invalid("strides", 0.0, "must be at least 1"));
    }
    let sc = &loaded.scenario;
    let mut leg = build_leg(loaded, Mount::default())?;
    let mut patient = build_patient(sc, &leg)?;
    let gait = GaitReference::normative(sc.gait.speed, sc.gait.stride_period_s, sc.gait.ramp_s)?;
    let stride_s = gait.stride_period_s();
    let start_s = (gait.ramp_s() / stride_s).ceil() * stride_s + stride_s;
    let end_s = start_s + strides as f64 * stride_s;
    let periods = (end_s / sc.period_s).round() as usize;
    if let Some(p) = &mut patient {
        p.plan(end_s + sc.period_s);
        p.reset();
    }
    let mut metrics = TreadmillMetrics::new(&leg, &gait, [0, 0, 1, 1], end_s, sc.period_s);
    let h = leg.substep_s();
    let mut samples = Vec::with_capacity(((end_s - start_s) / sc.period_s) as usize + 2);
    let mut max_error = [0.0f64; 2];
    for k in 0..periods {
        let t0 = k as f64 * sc.period_s;
        let mut sum = [0.0; 2];
        leg.step(|l, sub| {
            let t = t0 + sub as f64 * h;
            let servo = servo_torques(l, &gait, t);
            let patient_nm = match &mut patient {
                Some(p) => p.torques(t, l.angles(), l.velocities()).total(),
                None => [0.0; 2],
            };
            sum[0] += servo[0];
            sum[1] += servo[1];
            [servo[0] + patient_nm[0], servo[1] + patient_nm[1]]
        });
        let t = t0 + sc.period_s;
        let (q, qd) = (leg.angles(), leg.velocities());
        if !(q.iter().chain(&qd).all(|v| v.is_finite())) {
            return Err(LegError::LeftPhysics {
                t_s: t,
                what: "the servo-driven leg: its state is not finite".into(),
            });
        }
        let g = gait.sample(t);
        let error_deg = [
            (g.hip.angle_rad - q[0]).to_degrees(),
            (g.knee.angle_rad - q[1]).to_degrees(),
        ];
        if let (Some(m), Some(ground)) = (&mut metrics, leg.ground_reaction()) {
            m.push(&GroundPeriod {
                t_s: t,
                dt_s: sc.period_s,
                ground,
                pelvis_height_m: leg.pelvis_height_m().unwrap_or(f64::NAN),
                error_deg,
                pressure_pa: [f64::NAN; 4],
            });
        }
        if t > start_s + 0.5 * sc.period_s {
            let n = f64::from(leg.substeps());
            samples.push(DemandSample {
                t_s: t,
                angle_rad: q,
                velocity_rad_s: qd,
                torque_nm: [sum[0] / n, sum[1] / n],
            });
            for j in 0..2 {
                max_error[j] = max_error[j].max(error_deg[j].abs());
            }
        }
    }
    Ok(Demand {
        samples,
        max_error_deg: max_error,
        treadmill: metrics.map(|m| m.report()),
    })
}

/// The servos' torques at `t_s` (N m): stiff springs and dampers to the reference.
fn servo_torques(leg: &Leg, gait: &GaitReference, t_s: f64) -> [f64; 2] {
    let (q, qd) = (leg.angles(), leg.velocities());
    let g = gait.sample(t_s);
    let reference = [
        (g.hip.angle_rad, g.hip.velocity_rad_s),
        (g.knee.angle_rad, g.knee.velocity_rad_s),
    ];
    std::array::from_fn(|j| {
        SERVO_STIFFNESS_NM_PER_RAD * (reference[j].0 - q[j])
            + SERVO_DAMPING_NM_S_PER_RAD * (reference[j].1 - qd[j])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Scenario;

    #[test]
    fn in_the_air_the_servos_supply_the_legs_inverse_dynamics() {
        // Without a belt the joints need what the two-link pendulum's Lagrange equations
        // give for the reference's motion, plus the joints' damping.
        let loaded = Scenario::load("gait_training").expect("embedded");
        let d = stride_demand(&loaded, 1).expect("demand");
        let sc = &loaded.scenario;
        let leg = build_leg(&loaded, Mount::default()).expect("leg");
        let gait = GaitReference::normative(sc.gait.speed, sc.gait.stride_period_s, sc.gait.ramp_s)
            .expect("gait");
        let damping = [
            sc.joints.hip.damping_nm_s_per_rad,
            sc.joints.knee.damping_nm_s_per_rad,
        ];
        let (mut err2, mut tau2) = ([0.0; 2], [0.0; 2]);
        for s in &d.samples {
            // The torque was applied over the period before the sample.
            let g = gait.sample(s.t_s - 0.5 * sc.period_s);
            let (q, qd, qdd) = (
                [g.hip.angle_rad, g.knee.angle_rad],
                [g.hip.velocity_rad_s, g.knee.velocity_rad_s],
                [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2],
            );
            let id = leg.inertia().inverse_dynamics(q, qd, qdd);
            for j in 0..2 {
                let expected = id[j] + damping[j] * qd[j];
                err2[j] += (s.torque_nm[j] - expected).powi(2);
                tau2[j] += expected.powi(2);
            }
        }
        for j in 0..2 {
            let relative = (err2[j] / tau2[j]).sqrt();
            eprintln!(
                "joint {j}: servo vs inverse dynamics, RMS difference {:.2} % of the RMS torque",
                100.0 * relative
            );
            assert!(relative < 0.03, "joint {j}: {relative}");
        }
        assert!(d.treadmill.is_none());
    }
}
