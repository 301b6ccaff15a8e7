//! What a stride asks of the joints: the scenario's exoskeleton (on its treadmill, with its
//! patient, harness and other leg) driven along the reference by stiff joint servos instead
//! of muscles, and the torques those servos apply. It is inverse dynamics with the contact
//! forces in it: the servos supply whatever the gait, the belt and the patient need, and
//! the muscles that replace them must supply the same.
use crate::base::{invalid, LegError, PerLeg};
use crate::body::{Exoskeleton, Mount};
use crate::gait::GaitReference;
use crate::metrics::{FootMetrics, GroundPeriod, TrainerGroundMetrics, TreadmillReport};
use crate::scenario::LoadedScenario;
use crate::sim::{build_exo, build_patients};

/// Stiffness of the joint servos (N m/rad): 1 deg of error for 350 N m; tracking within a
/// few tenths of a degree on the treadmill (reported as [`Demand::max_error_deg`]).
pub const SERVO_STIFFNESS_NM_PER_RAD: f64 = 20_000.0;
/// Damping of the joint servos (N m s/rad) on the legs the URDF was built for (a 75 kg
/// patient's): about critical for the knee's inertia. A lighter or heavier patient's servos
/// damp in proportion to the leg's mass ([`servo_damping_nm_s_per_rad`]).
pub const SERVO_DAMPING_NM_S_PER_RAD: f64 = 150.0;

/// The joint servos' damping for a leg weighing `leg_kg` (frame and patient) where the
/// URDF's patient's weighs `urdf_leg_kg`, `length_ratio` times as long (N m s/rad):
/// [`SERVO_DAMPING_NM_S_PER_RAD`] scaled by the legs' inertia ratio, mass times length
/// squared. The servo's damping acts explicitly over the physics step, and its bound
/// (`c h / I < 2` for an effective inertia `I`) falls with the leg's inertia: the fixed
/// 150 N m s/rad let a 50 kg patient's servo-driven knee run away within 41 ms (55 kg:
/// 0.54 s), and scaled by mass alone a 1.50 m patient's within 50 ms (issue 47). Scaled,
/// every patient keeps the 75 kg, 1.75 m patient's distance to the bound and the same
/// damping per unit of inertia.
pub fn servo_damping_nm_s_per_rad(leg_kg: f64, urdf_leg_kg: f64, length_ratio: f64) -> f64 {
    // The ratio first: the URDF's own patient keeps 150 to the bit.
    SERVO_DAMPING_NM_S_PER_RAD * (leg_kg / urdf_leg_kg) * (length_ratio * length_ratio)
}

/// The servos' torques are averaged over this window (s) before they count as the
/// stride's demand: a muscle behind a valve cannot deliver a transient shorter than the
/// valve's lag (tens of milliseconds), and the compliant contact's stick-slip makes
/// one-period spikes on the belt (a heel rolling off while the other foot swings: +228 then
/// -246 N m at the knee in successive periods, docs/treadmill.md). The raw extremes are
/// kept in [`Demand::raw_torque_range_nm`].
pub const DEMAND_WINDOW_S: f64 = 0.01;

/// One period of one leg of the servo-driven stride.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemandSample {
    /// Time (s).
    pub t_s: f64,
    /// The leg (0 right, 1 left).
    pub leg: usize,
    /// Phase of the leg's gait cycle (0-1, 0 at its initial contact).
    pub phase: f64,
    /// Joint angles (rad), hip and knee.
    pub angle_rad: [f64; 2],
    /// Joint velocities (rad/s).
    pub velocity_rad_s: [f64; 2],
    /// Torque the joints need (N m, flexion positive): the servos' averaged over
    /// [`DEMAND_WINDOW_S`] about the period.
    pub torque_nm: [f64; 2],
    /// The leg's foot's vertical and fore-aft ground reaction (N; NaN in the air).
    pub grf_n: [f64; 2],
    /// The passive ankle's angle (rad; NaN without one).
    pub ankle_rad: f64,
    /// The pelvis frame `[fore-aft, height]` (m; NaN in the air).
    pub pelvis_m: [f64; 2],
    /// The foot's slip on the belt (m/s; NaN in the air).
    pub slip_m_s: f64,
    /// Fore-aft speed of the foot where it touches the belt, relative to the hip (m/s,
    /// forward positive; NaN out of contact): a stance foot that moves with the belt has
    /// minus the belt's speed here at every instant (see [`crate::fit_gait()`]).
    pub contact_speed_m_s: f64,
}

/// The joints' demand over whole strides.
#[derive(Debug, Clone, PartialEq)]
pub struct Demand {
    /// The periods of the strides measured, after the start-up ramp and one stride: every
    /// leg's, period after period.
    pub samples: Vec<DemandSample>,
    /// Number of legs.
    pub legs: usize,
    /// Largest tracking error of the servos over them (deg), hip and knee, of any leg.
    pub max_error_deg: [f64; 2],
    /// The servos' own extremes, period by period before the averaging, per joint
    /// `[extension, flexion]` (N m).
    pub raw_torque_range_nm: [[f64; 2]; 2],
    /// The treadmill's figures of the servo-driven run (`None` in the air).
    pub treadmill: Option<TreadmillReport>,
}

impl Demand {
    /// Largest flexion and extension torque of joint `j` of any leg (N m; extension
    /// negative).
    pub fn torque_range_nm(&self, j: usize) -> [f64; 2] {
        self.samples
            .iter()
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], s| {
                [lo.min(s.torque_nm[j]), hi.max(s.torque_nm[j])]
            })
    }

    /// Largest |velocity| of joint `j` of any leg (rad/s).
    pub fn peak_speed_rad_s(&self, j: usize) -> f64 {
        self.samples
            .iter()
            .map(|s| s.velocity_rad_s[j].abs())
            .fold(0.0, f64::max)
    }

    /// Leg `leg`'s samples.
    pub fn of_leg(&self, leg: usize) -> impl Iterator<Item = &DemandSample> {
        self.samples.iter().filter(move |s| s.leg == leg)
    }
}

/// The scenario's exoskeleton driven along its gait by the joint servos for the start-up
/// ramp and `strides + 1` strides; the last `strides` are measured.
pub fn stride_demand(loaded: &LoadedScenario, strides: usize) -> Result<Demand, LegError> {
    if strides == 0 {
        return Err(invalid("strides", 0.0, "must be at least 1"));
    }
    let sc = &loaded.scenario;
    let mut exo = build_exo(loaded, Mount::default())?;
    let legs = exo.leg_count();
    let mut patients = build_patients(sc, &exo)?;
    let gait = sc.gait.reference()?;
    let gaits: Vec<GaitReference> = (0..legs).map(|l| gait.for_leg(l)).collect();
    let stride_s = gait.stride_period_s();
    let start_s = gait.measured_from_s();
    let end_s = start_s + strides as f64 * stride_s;
    let periods = (end_s / sc.period_s).round() as usize;
    for p in &mut patients {
        p.plan(end_s + sc.period_s);
        p.reset();
    }
    let mut feet: Vec<FootMetrics> = gaits
        .iter()
        .filter_map(|g| FootMetrics::new(&exo, g, end_s, sc.period_s))
        .collect();
    let mut ground = TrainerGroundMetrics::new(&exo, start_s);
    let h = exo.substep_s();
    let damping = leg_servo_damping(loaded, &exo);
    let mut samples = Vec::with_capacity(legs * (((end_s - start_s) / sc.period_s) as usize + 2));
    let mut max_error = [0.0f64; 2];
    for k in 0..periods {
        let t0 = k as f64 * sc.period_s;
        let mut sum = [[0.0; 2]; crate::base::MAX_LEGS];
        exo.step(|e, sub| {
            let t = t0 + sub as f64 * h;
            PerLeg::from_fn(legs, |leg| {
                let servo = servo_torques(e, leg, &gaits[leg], t, damping);
                let patient_nm = match patients.get_mut(leg) {
                    Some(p) => p.torques(t, e.angles(leg), e.velocities(leg)).total(),
                    None => [0.0; 2],
                };
                sum[leg][0] += servo[0];
                sum[leg][1] += servo[1];
                [servo[0] + patient_nm[0], servo[1] + patient_nm[1]]
            })
        });
        let t = t0 + sc.period_s;
        let reaction = exo.ground_reaction();
        if let (Some(g), Some(pelvis)) = (&reaction, exo.pelvis_position_m()) {
            ground.push(t, sc.period_s, g, pelvis);
        }
        for leg in 0..legs {
            let (q, qd) = (exo.angles(leg), exo.velocities(leg));
            // A diverging servo run is caught as the closed loop's is: before it turns
            // into demands of 1e28 N m/kg (issue 47: a 55 kg patient's foot, whose moment
            // of inertia had gone negative, and the 75 kg patient's servo damping).
            let limits = exo.limits_rad(leg);
            for (j, joint) in ["hip", "knee"].iter().enumerate() {
                if let Some(why) = crate::plant::left_physics(q[j], qd[j], limits[j]) {
                    return Err(LegError::LeftPhysics {
                        t_s: t,
                        what: format!("the servo-driven {joint}: {why}"),
                    });
                }
            }
            let g = gaits[leg].sample(t);
            let error_deg = [
                (g.hip.angle_rad - q[0]).to_degrees(),
                (g.knee.angle_rad - q[1]).to_degrees(),
            ];
            let ankle_rad = exo.ankle(leg).map_or(f64::NAN, |a| a.0);
            let foot = reaction.as_ref().and_then(|r| r.feet.get(leg).copied());
            if let (Some(m), Some(foot)) = (feet.get_mut(leg), foot) {
                m.push(&GroundPeriod {
                    t_s: t,
                    dt_s: sc.period_s,
                    foot,
                    error_deg,
                    pressure_pa: [f64::NAN; 4],
                    ankle_rad,
                });
            }
            if t > start_s + 0.5 * sc.period_s {
                let n = f64::from(exo.substeps());
                samples.push(DemandSample {
                    t_s: t,
                    leg,
                    phase: gaits[leg].phase(t),
                    angle_rad: q,
                    velocity_rad_s: qd,
                    torque_nm: [sum[leg][0] / n, sum[leg][1] / n],
                    grf_n: foot.map_or([f64::NAN; 2], |f| [f.vertical_n, f.fore_aft_n]),
                    ankle_rad,
                    pelvis_m: exo.pelvis_position_m().unwrap_or([f64::NAN; 2]),
                    slip_m_s: foot.map_or(f64::NAN, |f| f.slip_m_s),
                    contact_speed_m_s: contact_speed(&exo, foot.as_ref()),
                });
                for j in 0..2 {
                    max_error[j] = max_error[j].max(error_deg[j].abs());
                }
            }
        }
    }
    let raw_torque_range_nm = [0, 1].map(|j| {
        samples
            .iter()
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], s| {
                [lo.min(s.torque_nm[j]), hi.max(s.torque_nm[j])]
            })
    });
    let half = (0.5 * DEMAND_WINDOW_S / sc.period_s).round() as usize;
    average_per_leg(&mut samples, legs, half);
    Ok(Demand {
        samples,
        legs,
        max_error_deg: max_error,
        raw_torque_range_nm,
        treadmill: ground.report(feet.iter().map(FootMetrics::report).collect()),
    })
}

/// Fore-aft speed of `foot`'s contact relative to the hip (m/s): its slip against the belt,
/// less the belt's speed and the pelvis's. NaN without a loaded contact.
fn contact_speed(exo: &Exoskeleton, foot: Option<&crate::ground::FootReaction>) -> f64 {
    match (foot, exo.ground(), exo.pelvis_velocity_m_s()) {
        (Some(f), Some(g), Some(pelvis)) if f.vertical_n > crate::metrics::CONTACT_THRESHOLD_N => {
            f.fore_aft_slip_m_s - g.belt_speed_now_m_s() - pelvis[0]
        }
        _ => f64::NAN,
    }
}

/// Each leg's torques replaced by their centred moving average over `2 half + 1` periods
/// (fewer at the ends); `samples` are period after period, `legs` per period.
fn average_per_leg(samples: &mut [DemandSample], legs: usize, half: usize) {
    if half == 0 || legs == 0 {
        return;
    }
    for leg in 0..legs {
        let raw: Vec<[f64; 2]> = samples
            .iter()
            .filter(|s| s.leg == leg)
            .map(|s| s.torque_nm)
            .collect();
        let n = raw.len();
        for (k, s) in samples.iter_mut().filter(|s| s.leg == leg).enumerate() {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(n));
            let window = &raw[a..b];
            s.torque_nm =
                [0, 1].map(|j| window.iter().map(|t| t[j]).sum::<f64>() / window.len() as f64);
        }
    }
}

/// The most a joint's peak demand may be over the adults' peak moment before `size`
/// refuses to recommend muscles for it, and `simulate` to run it: the shipped trainer asks
/// 2.3 times the adults' at the hip (its pelvis cannot pitch, so the hip holds what the
/// subjects' trunk balanced; docs/treadmill.md) and 1.5 times at the knee; belts within
/// 1 % of the fitted 0.4855 m/s ask up to 4.2 times (0.490 m/s); one 7 % faster (0.52
/// m/s, where the knee's stance RMS is 2.1 deg) asks 16 times, at 0.7 m/s (a collapse)
/// 24 times: a scenario that does not fit its gait data.
pub const DEMAND_OVER_NORM_MAX: f64 = 5.0;

impl NormComparison {
    /// The joint's peak demand over the adults' peak moment.
    pub fn ratio(&self) -> f64 {
        self.peak_demand_nm_kg / self.peak_normative_nm_kg
    }
}

/// A joint's demand over the gait cycle beside the adult normative moment (per kilogram of
/// the patient's body mass, flexion positive), at 0, 1, ..., 100 % of each leg's cycle.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NormComparison {
    /// `hip` or `knee`.
    pub joint: String,
    /// The servos' torque averaged over the strides and legs at each per cent of the
    /// cycle (N m/kg).
    pub demand_nm_kg: Vec<f64>,
    /// The normative internal moment turned into the torque the joint needs (flexion
    /// positive: minus the extensor moment), unsupported walking (N m/kg).
    pub normative_nm_kg: Vec<f64>,
    /// Largest |demand| over the cycle (N m/kg).
    pub peak_demand_nm_kg: f64,
    /// Largest |normative| (N m/kg).
    pub peak_normative_nm_kg: f64,
    /// RMS of demand minus normative over the cycle (N m/kg).
    pub rms_difference_nm_kg: f64,
    /// The same against the normative moment scaled by `1 - bws_fraction` (the share of
    /// the weight the legs carry; support lowers stance moments roughly so, swing's less).
    pub rms_difference_supported_nm_kg: f64,
}

/// The adults' loading response beside the trainer's feet: the mean vertical ground
/// reaction of the adult data at the reference's speed, scaled by `1 - bws_fraction` as
/// the moments are, measured as the feet are ([`crate::gait::loading`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NormLoading {
    /// The mean curve's loading peak times `1 - bws_fraction` (body weights).
    pub peak_bw: f64,
    /// That peak over the mean load the belt carries, `1 - bws_fraction` body weights: the
    /// figure a foot's `peak_grf_bw / expected_belt_load_bw` compares with.
    pub peak_over_load: f64,
    /// The mean curve's loading rate over the reference's stride, times `1 -
    /// bws_fraction` (body weights per second).
    pub loading_rate_bw_s: f64,
    /// The adults' mean stance fraction (toe-off).
    pub stance_fraction: f64,
    /// The stride the curve is timed over: the reference's (s).
    pub stride_s: f64,
}

/// The adults' loading response (`norms`) over the reference's stride of `stride_s`,
/// sampled every `dt_s`, on `bws_fraction` support.
pub fn norm_loading(
    norms: &crate::gait::AdultNorms,
    stride_s: f64,
    dt_s: f64,
    bws_fraction: f64,
) -> NormLoading {
    let l = norms.grf_loading(stride_s, dt_s);
    let scale = 1.0 - bws_fraction;
    NormLoading {
        peak_bw: l.peak * scale,
        peak_over_load: l.peak,
        loading_rate_bw_s: l.rate * scale,
        stance_fraction: norms.toe_off,
        stride_s,
    }
}

/// Each joint's demand over the cycle beside `norms` (the adult data at the reference's
/// speed), for a patient of `body_mass_kg` on `bws_fraction` support.
pub fn against_norms(
    demand: &Demand,
    norms: &crate::gait::AdultNorms,
    body_mass_kg: f64,
    bws_fraction: f64,
) -> Vec<NormComparison> {
    let n = crate::gait::CURVE_SAMPLES;
    ["hip", "knee"]
        .into_iter()
        .zip(norms.flexion_torques_nm_kg())
        .enumerate()
        .map(|(j, (name, norm))| {
            let mut sum = vec![0.0; n];
            let mut count = vec![0usize; n];
            for s in &demand.samples {
                let bin = ((s.phase * (n - 1) as f64).round() as usize).min(n - 1);
                sum[bin] += s.torque_nm[j] / body_mass_kg;
                count[bin] += 1;
            }
            let demand_nm_kg: Vec<f64> = sum
                .iter()
                .zip(&count)
                .map(|(s, c)| if *c > 0 { s / *c as f64 } else { f64::NAN })
                .collect();
            let rms = |scale: f64| {
                let (sq, k) = demand_nm_kg
                    .iter()
                    .zip(&norm)
                    .filter(|(d, _)| d.is_finite())
                    .fold((0.0, 0usize), |(sq, k), (d, m)| {
                        (sq + (d - scale * m).powi(2), k + 1)
                    });
                (sq / k.max(1) as f64).sqrt()
            };
            let peak = |v: &[f64]| {
                v.iter()
                    .filter(|x| x.is_finite())
                    .fold(0.0f64, |p, x| p.max(x.abs()))
            };
            NormComparison {
                joint: name.to_owned(),
                peak_demand_nm_kg: peak(&demand_nm_kg),
                peak_normative_nm_kg: peak(&norm),
                rms_difference_nm_kg: rms(1.0),
                rms_difference_supported_nm_kg: rms(1.0 - bws_fraction),
                demand_nm_kg,
                normative_nm_kg: norm,
            }
        })
        .collect()
}

/// The servos' damping for `loaded`'s legs (N m s/rad): on a treadmill the patient's legs
/// weigh what its body mass says (Winter's fractions) and are as long as its height says,
/// and the damping follows their inertia.
fn leg_servo_damping(loaded: &LoadedScenario, exo: &Exoskeleton) -> f64 {
    let Some(treadmill) = &loaded.scenario.treadmill else {
        return SERVO_DAMPING_NM_S_PER_RAD;
    };
    let i = exo.inertia();
    let leg_kg = i.thigh.mass_kg + i.shank.mass_kg;
    let extra_kg = crate::body::LEG_MASS_FRACTION
        * (treadmill.body_mass_kg - crate::body::URDF_PATIENT_MASS_KG);
    let length_ratio = treadmill
        .height_m
        .map_or(1.0, |h| h / crate::body::URDF_PATIENT_HEIGHT_M);
    servo_damping_nm_s_per_rad(leg_kg, leg_kg - extra_kg, length_ratio)
}

/// Leg `leg`'s servos' torques at `t_s` (N m): stiff springs and dampers (`damping`, N m
/// s/rad) to its reference.
fn servo_torques(
    exo: &Exoskeleton,
    leg: usize,
    gait: &GaitReference,
    t_s: f64,
    damping: f64,
) -> [f64; 2] {
    let (q, qd) = (exo.angles(leg), exo.velocities(leg));
    let g = gait.sample(t_s);
    let reference = [
        (g.hip.angle_rad, g.hip.velocity_rad_s),
        (g.knee.angle_rad, g.knee.velocity_rad_s),
    ];
    std::array::from_fn(|j| {
        SERVO_STIFFNESS_NM_PER_RAD * (reference[j].0 - q[j]) + damping * (reference[j].1 - qd[j])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn in_the_air_the_servos_supply_the_legs_inverse_dynamics() {
        // Without a belt the joints need what the two-link pendulum's Lagrange equations
        // give for the reference's motion, plus the joints' damping.
        let loaded = Scenario::load("gait_training").expect("embedded");
        let d = stride_demand(&loaded, 1).expect("demand");
        let sc = &loaded.scenario;
        let exo = build_exo(&loaded, Mount::default()).expect("leg");
        let gait = sc.gait.reference().expect("gait");
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
            let id = exo.inertia().inverse_dynamics(q, qd, qdd);
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

    /// Issue 47: a 50 kg patient's servo-driven knee turned at 50.5 rad/s within 41 ms
    /// (once its foot's inertia was a body's; 14 ms before), under the 75 kg patient's
    /// servo damping acting explicitly on a lighter leg. Damped in proportion to the leg's
    /// mass, the stride runs and tracks as the 75 kg patient's does; the URDF's patient
    /// keeps the shipped damping exactly.
    #[test]
    fn regression_a_light_patients_servo_driven_knee_ran_away() {
        let mut loaded = Scenario::load("gait_treadmill").expect("embedded");
        let shipped = stride_demand(&loaded, 1).expect("75 kg");
        let exo = build_exo(&loaded, Mount::default()).expect("trainer");
        assert_eq!(leg_servo_damping(&loaded, &exo), SERVO_DAMPING_NM_S_PER_RAD);
        if let Some(t) = loaded.scenario.treadmill.as_mut() {
            t.body_mass_kg = 50.0;
        }
        let exo = build_exo(&loaded, Mount::default()).expect("trainer");
        let damping = leg_servo_damping(&loaded, &exo);
        assert!((100.0..120.0).contains(&damping), "{damping}");
        // Tracks as the 75 kg patient's stride does: within twice its largest error.
        let tracks_as_shipped = |d: &Demand| {
            for j in 0..2 {
                assert!(
                    d.max_error_deg[j] < 2.0 * shipped.max_error_deg[j].max(0.1),
                    "joint {j}: {} deg against {}",
                    d.max_error_deg[j],
                    shipped.max_error_deg[j]
                );
            }
        };
        tracks_as_shipped(&stride_demand(&loaded, 1).expect("50 kg: the servo-driven stride runs"));
        // The shortest patient the frame takes (1.47 m): damped by mass alone, the knee ran
        // away within 32 ms; by the leg's inertia (mass times length squared) it runs.
        if let Some(t) = loaded.scenario.treadmill.as_mut() {
            t.height_m = Some(1.47);
            t.speed_m_per_s = t.speed_m_per_s.map(|v| v * 1.47 / 1.75);
        }
        let exo = build_exo(&loaded, Mount::default()).expect("trainer");
        let short = leg_servo_damping(&loaded, &exo);
        assert!(
            (short - damping * (1.47f64 / 1.75).powi(2)).abs() < 1e-9,
            "{short}"
        );
        tracks_as_shipped(&stride_demand(&loaded, 1).expect("50 kg, 1.47 m: the stride runs"));
    }
}
