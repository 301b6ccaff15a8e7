use crate::base::{invalid, LegError, JOINT_NAMES};
use crate::body::{Exoskeleton, Mount};
use crate::control::{Compensation, ControlMode};
use crate::ground::Contralateral;
use crate::metrics::OnLeg;
use crate::patient::Patient;
use crate::plant::{MuscleActuator, MuscleGeometry, LIMIT_OVERSHOOT_MAX_RAD};
use crate::scenario::{LoadedScenario, Scenario};
use crate::sim::LegSim;
use pma_control::supervisor::{ReadingWindow, SupervisorLimits};
use pma_control::ControllerConfig;
use pma_loop::LoopSettings;
use pma_model::{MuscleModel, MuscleParams, Valve};

/// The weight a stance leg carries on `exo`'s treadmill, when the scenario's impedance
/// settings hold it (`None` in the air or with `stance_load = false`).
pub(crate) fn stance_load(
    sc: &Scenario,
    exo: &Exoskeleton,
) -> Result<Option<crate::control::StanceLoad>, LegError> {
    let Some(ground) = exo.ground().filter(|_| sc.control.impedance.stance_load) else {
        return Ok(None);
    };
    let toe_off = sc.gait.reference()?.toe_off_phase();
    Ok(Some(crate::control::StanceLoad::new(
        ground.chain().clone(),
        ground.total_mass_kg(),
        *ground.settings(),
        toe_off,
    )))
}

/// Each leg's patient (empty: the passive limb). The second leg's spasms are drawn from
/// the scenario's seeds plus one, so the legs do not jerk together.
pub(crate) fn build_patients(sc: &Scenario, exo: &Exoskeleton) -> Result<Vec<Patient>, LegError> {
    if sc.patient.is_passive() {
        return Ok(Vec::new());
    }
    let gait = sc.gait.reference()?;
    let damping = [
        sc.joints.hip.damping_nm_s_per_rad,
        sc.joints.knee.damping_nm_s_per_rad,
    ];
    let walking = walking_moments(sc, &gait)?;
    (0..exo.leg_count())
        .map(|leg| {
            let settings = sc.patient.for_leg(leg);
            let mut p = Patient::new(
                &settings,
                exo.substep_s(),
                gait.for_leg(leg),
                *exo.inertia(),
                damping,
            )?;
            if let Some(m) = &walking {
                p.walk_with_moments(m.clone(), sc.treadmill);
            }
            Ok(p)
        })
        .collect()
}

/// The joint moments an active patient who walks on the belt produces
/// ([`crate::patient::OwnTorque::Walking`]): the adults' mean moments at the reference's
/// speed, flexion positive, times the body mass and the share the legs carry; `None` for
/// a patient on their limb's inverse dynamics.
fn walking_moments(
    sc: &Scenario,
    gait: &crate::gait::GaitReference,
) -> Result<Option<[Vec<f64>; 2]>, LegError> {
    let Some(active) = &sc.patient.active else {
        return Ok(None);
    };
    if active.own_torque != crate::patient::OwnTorque::Walking {
        return Ok(None);
    }
    adult_moments(
        sc,
        gait,
        [
            "patient.active.own_torque = \"walking\" needs a treadmill (its body mass and support)",
            "patient.active.own_torque = \"walking\" produces the adult data's moments",
        ],
    )
    .map(Some)
}

/// The adults' mean walking moments at the reference's speed (N m, flexion positive, at
/// 0, 1, ..., 100 % of the cycle), times the body mass and the share of the weight the
/// legs carry under constant support, as `pma-exo size` scales the moments it compares
/// with; `hints` say what needs the treadmill and the adult data.
fn adult_moments(
    sc: &Scenario,
    gait: &crate::gait::GaitReference,
    hints: [&'static str; 2],
) -> Result<[Vec<f64>; 2], LegError> {
    // Walking's moments carry a stance, which needs a belt, a body and the adult data.
    let treadmill = sc.treadmill.as_ref().ok_or_else(|| LegError::Missing {
        name: "[treadmill]".into(),
        hint: hints[0],
    })?;
    let speed = gait.data_speed_m_s().ok_or_else(|| LegError::Missing {
        name: "gait.data = \"fukuchi2018\"".into(),
        hint: hints[1],
    })?;
    let norms = crate::gait::AdultNorms::at(speed)?;
    let scale = treadmill.body_mass_kg * (1.0 - treadmill.bws_fraction);
    Ok(norms
        .flexion_torques_nm_kg()
        .map(|c| c.iter().map(|t| t * scale).collect()))
}

/// Checks, for setting `field` to `value`, that the scenario's mode yields to the patient
/// (impedance or admittance) and, if `plans` (a share of a plan left to them), that it
/// plans the limb's torque (admittance carrying the leg, not only the device).
fn yielding_mode(sc: &Scenario, field: &str, value: f64, plans: bool) -> Result<(), LegError> {
    let unsupported = |message: &str| LegError::Unsupported {
        name: field.into(),
        value: format!("{value}"),
        message: message.into(),
    };
    match sc.control.mode {
        ControlMode::Impedance => Ok(()),
        ControlMode::Admittance if !plans || sc.control.compensation == Compensation::Leg => {
            Ok(())
        }
        ControlMode::Admittance => Err(unsupported(
            "with compensation = \"device\" admittance mode plans none of the limb's torque to leave to the patient",
        )),
        _ => Err(unsupported(
            "only impedance and admittance modes yield to the patient",
        )),
    }
}

/// The gait's clock following the legs' lead (`control.impedance.phase_sync_per_s`;
/// `None` at 0).
pub(crate) fn phase_sync(sc: &Scenario) -> Result<Option<crate::control::PhaseSync>, LegError> {
    let (gain, integral) = (
        sc.control.impedance.phase_sync_per_s,
        sc.control.impedance.phase_sync_integral_per_s2,
    );
    if gain == 0.0 && integral == 0.0 {
        return Ok(None);
    }
    let (field, value) = if gain != 0.0 {
        ("control.impedance.phase_sync_per_s", gain)
    } else {
        ("control.impedance.phase_sync_integral_per_s2", integral)
    };
    yielding_mode(sc, field, value, false)?;
    if sc
        .treadmill
        .is_some_and(|t| t.other_leg() == Contralateral::Reference)
    {
        return Err(LegError::Unsupported {
            name: field.into(),
            value: format!("{value}"),
            message: "the virtual other leg walks on the reference's own clock: give the trainer two legs".into(),
        });
    }
    let gait = sc.gait.reference()?;
    let stride = gait.stride_period_s();
    // The reference's Σ q̇² over one stride after the start-up, every leg alike.
    let n = 200;
    let start = (gait.ramp_s() / stride).ceil() * stride;
    let mean_power = (0..n)
        .map(|k| {
            let g = gait.sample(start + k as f64 / n as f64 * stride);
            g.hip.velocity_rad_s.powi(2) + g.knee.velocity_rad_s.powi(2)
        })
        .sum::<f64>()
        / n as f64
        * sc.treadmill.map_or(1, |t| t.legs) as f64;
    crate::control::PhaseSync::new(gain, integral, stride, mean_power).map(Some)
}

/// The moments impedance or admittance mode leaves to leg `leg`'s walking patient
/// (`control.impedance.patient_moment_share`, or its `_by_leg`; `None` at 0).
pub(crate) fn expected_moments(
    sc: &Scenario,
    leg: usize,
) -> Result<Option<crate::control::ExpectedMoments>, LegError> {
    let share = sc.control.impedance.patient_moment_share(leg);
    if share == 0.0 {
        return Ok(None);
    }
    yielding_mode(sc, "control.impedance.patient_moment_share", share, true)?;
    const NEEDS_TREADMILL: &str =
        "control.impedance.patient_moment_share > 0 needs a treadmill (its body mass and support)";
    let support = sc.treadmill.ok_or_else(|| LegError::Missing {
        name: "[treadmill]".into(),
        hint: NEEDS_TREADMILL,
    })?;
    let gait = sc.gait.reference()?;
    let moments = adult_moments(
        sc,
        &gait,
        [
            NEEDS_TREADMILL,
            "control.impedance.patient_moment_share > 0 leaves the adult data's moments to the patient",
        ],
    )?;
    Ok(Some(crate::control::ExpectedMoments::new(
        moments, share, support,
    )))
}

/// The scenario's exoskeleton: a fixed pelvis (as `mount` says), or its treadmill, the
/// belt at the reference's speed unless the scenario gives one, a one-leg trainer's
/// virtual other leg added and the legs standing at rest on the belt.
pub(crate) fn build_exo(loaded: &LoadedScenario, mount: Mount) -> Result<Exoskeleton, LegError> {
    let sc = &loaded.scenario;
    let joints = [sc.joints.hip, sc.joints.knee];
    let Some(treadmill) = &sc.treadmill else {
        let mut exo = Exoskeleton::mounted(
            &loaded.urdf_text,
            &loaded.urdf_source,
            joints,
            sc.period_s,
            sc.physics_substeps,
            mount,
        )?;
        exo.take_start_pose(&sc.gait.reference()?);
        return Ok(exo);
    };
    if mount != Mount::default() {
        return Err(LegError::Parse {
            file: sc.name.clone(),
            message: "a treadmill scenario's leg stands on its belt: it cannot be mounted on a seat (pendulum test)".into(),
        });
    }
    let gait = sc.gait.reference()?;
    let mut exo = Exoskeleton::on_treadmill(
        &loaded.urdf_text,
        &loaded.urdf_source,
        joints,
        sc.period_s,
        sc.physics_substeps,
        treadmill,
    )?;
    if treadmill.speed_m_per_s.is_none() {
        exo.belt_at_reference_speed(&gait);
    }
    exo.ramp_belt(gait.ramp_s());
    if treadmill.other_leg() == Contralateral::Reference {
        exo.add_other_leg(gait);
    }
    exo.take_start_pose(&gait);
    exo.rest_on_belt();
    Ok(exo)
}

/// Each leg's joint errors and velocities (deg, deg/s) of every period of `origin`'s
/// simulation without its spasms, over `settings`' duration (no stop flag: it is short).
pub(crate) fn baseline_traces(
    origin: &(LoadedScenario, ControllerConfig, Mount),
    settings: &LoopSettings,
) -> Result<Vec<Vec<[f64; 4]>>, LegError> {
    let (loaded, config, mount) = origin;
    let mut calm = loaded.clone();
    calm.scenario.patient.hip.spasms = None;
    calm.scenario.patient.knee.spasms = None;
    let mut sim = LegSim::mounted(&calm, config, *mount)?;
    let periods = settings.periods(sim.scenario.period_s)?;
    let mut traces: Vec<OnLeg<crate::metrics::BaselineTrace>> = (0..sim.leg_count())
        .map(|leg| {
            OnLeg::new(
                leg,
                crate::metrics::BaselineTrace(Vec::with_capacity(periods as usize + 1)),
            )
        })
        .collect();
    // A baseline the supervisor stops still covers its periods up to the fault. The run's
    // own settings, stop flag included: the operator's stop ends the baseline too.
    let _ = sim.run_until_fault(settings, &mut traces)?;
    Ok(traces.into_iter().map(|t| t.inner.0).collect())
}

/// Full scale of a cuff torque sensor (N m): where admittance mode reads the cuffs, a
/// reading beyond it is a fault. Twice the largest interaction peak any shipped scenario
/// has shown (443 N m at the hip, the transparent leg swinging into a spasm's end of
/// range, docs/cooperative.md), so that only a broken or saturated reading trips it.
pub const CUFF_TORQUE_FULL_SCALE_NM: f64 = 1000.0;

/// What the supervisor enforces: every muscle's pressure within its valve's range and the
/// scenario's rate limit, each encoder finite and inside its joint's limits (with
/// [`LIMIT_OVERSHOOT_MAX_RAD`] to spare: rapier holds a limit to milliradians), each cuff
/// torque not NaN and, in admittance mode, the one mode whose loop reads it, within
/// [`CUFF_TORQUE_FULL_SCALE_NM`]; leg after leg. (The other modes do not stop a run on a
/// sensor they do not read: the reading is the frames' model's, meaningless on a URDF
/// whose links are lighter than the frames.)
pub(crate) fn supervisor_limits(sc: &Scenario, exo: &Exoskeleton) -> SupervisorLimits {
    const NAMES: [[&str; 8]; 2] = [
        [
            "hip angle",
            "knee angle",
            "hip cuff torque",
            "knee cuff torque",
            "muscle 1 pressure",
            "muscle 2 pressure",
            "muscle 3 pressure",
            "muscle 4 pressure",
        ],
        [
            "left hip angle",
            "left knee angle",
            "left hip cuff torque",
            "left knee cuff torque",
            "left muscle 1 pressure",
            "left muscle 2 pressure",
            "left muscle 3 pressure",
            "left muscle 4 pressure",
        ],
    ];
    let mut windows = Vec::with_capacity(8 * exo.leg_count());
    for leg in 0..exo.leg_count() {
        let limits = exo.limits_rad(leg);
        let names = NAMES[leg.min(1)];
        for k in 0..2 {
            let [lo, hi] = limits[k];
            windows.push(ReadingWindow {
                name: names[k],
                unit: "rad",
                min: lo - LIMIT_OVERSHOOT_MAX_RAD,
                max: hi + LIMIT_OVERSHOOT_MAX_RAD,
            });
        }
        let full_scale = if sc.control.mode == crate::control::ControlMode::Admittance {
            CUFF_TORQUE_FULL_SCALE_NM
        } else {
            f64::INFINITY
        };
        for name in &names[2..4] {
            windows.push(ReadingWindow {
                name,
                unit: "N m",
                min: -full_scale,
                max: full_scale,
            });
        }
        // A pressure sensor reads from vacuum to the valve's limit and 10 % beyond (a
        // reading above it: a valve stuck open or a wrong supply, as on the rig).
        for name in &names[4..] {
            windows.push(ReadingWindow {
                name,
                unit: "Pa",
                min: -pma_model::pneumatics::ATMOSPHERE_PA,
                max: 1.1 * sc.plant.valve.pressure_max_pa,
            });
        }
    }
    SupervisorLimits {
        pressure_max_pa: sc.plant.valve.pressure_max_pa,
        pressure_rate_max_pa_per_s: sc.control.pressure_rate_max_pa_per_s,
        windows,
        sensor_stuck_periods: 0,
        watchdog_periods: 0,
        overrun_max_consecutive_periods: u32::MAX,
        overrun_max_share: 1.0,
    }
}

/// Each leg's four muscles from the geometry (one leg's), leg after leg.
pub(crate) fn build_muscles(
    sc: &Scenario,
    geometry: &[MuscleGeometry],
    legs: usize,
) -> Result<Vec<MuscleActuator>, LegError> {
    if geometry.len() != 4 {
        return Err(invalid(
            "number of muscles",
            geometry.len() as f64,
            "must be 4: a flexor and an extensor on hip and knee",
        ));
    }
    let links: [(&str, [&str; 2]); 2] =
        [("hip", ["pelvis", "thigh"]), ("knee", ["thigh", "shank"])];
    let mut out = Vec::with_capacity(4);
    let flow_valve = sc.plant.flow_valve()?;
    for (index, g) in geometry.iter().enumerate() {
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
        let scale = sc.plant.muscle_scale.get(&g.name).copied();
        let festo_scale = sc.plant.festo_scale.get(&g.name).copied();
        let (model, (rated_force_n, rating)) = match (g.festo()?, scale) {
            (Some(festo), None) => {
                // The rating stays the datasheet's: a muscle off its figures is still
                // rated as the one bought.
                let festo = festo
                    .with_scale(festo_scale.unwrap_or_default())
                    .map_err(|e| LegError::from(e.within_section(&format!("plant.festo_scale.{}", g.name))))?;
                (
                    MuscleModel::Festo(festo),
                    (
                        festo.size.rated_force_n(),
                        format!("Festo {}", festo.size.name().to_uppercase()),
                    ),
                )
            }
            (Some(_), Some(_)) => return Err(err(
                "is a Festo muscle (`size`): plant.muscle_scale applies to Table I muscles only; [plant.festo_scale.<muscle>] scales a Festo muscle's force map, stiffness and damping"
                    .into(),
            )),
            (None, _) if festo_scale.is_some() => return Err(err(
                "is a Table I muscle: plant.festo_scale applies to Festo muscles (`size`) only; [plant.muscle_scale.<muscle>] scales Table I"
                    .into(),
            )),
            (None, scale) => {
                let params = scale.unwrap_or_default().apply(MuscleParams::TABLE_I);
                params.validate()?;
                (
                    MuscleModel::ThreeElement(params),
                    sc.plant.three_element_rating(),
                )
            }
        };
        out.push(MuscleActuator {
            geometry: g.clone(),
            leg: 0,
            index,
            joint,
            model,
            rated_force_n,
            rating,
            valve: Valve::new(sc.plant.valve_of(flow_valve.as_ref(), &model), 0.0)?,
        });
    }
    for name in sc
        .plant
        .muscle_scale
        .keys()
        .chain(sc.plant.festo_scale.keys())
    {
        if !geometry.iter().any(|g| &g.name == name) {
            return Err(LegError::Muscle {
                muscle: name.clone(),
                message: "plant.muscle_scale or plant.festo_scale names a muscle the geometry does not have".into(),
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
            return Err(invalid(
                format!("muscles on {joint_name}"),
                sides.len() as f64,
                "each joint needs exactly one flexor and one extensor",
            ));
        }
    }
    let one = out;
    let mut all = Vec::with_capacity(legs * one.len());
    for leg in 0..legs {
        all.extend(one.iter().cloned().map(|m| MuscleActuator { leg, ..m }));
    }
    Ok(all)
}
