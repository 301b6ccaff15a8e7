//! The exoskeleton leg through the public API: gait tracking, co-contraction over a long
//! run, energy and static equilibrium against hand calculations, bad input.
use pma_leg::body::EMBEDDED_URDF;
use pma_leg::{LegOutput, LegReport, LegSim, PerLeg, Scenario, Side, SupervisedLeg, TrainerSample};
use pma_loop::{FnRecorder, Period};

mod common;
use common::LONG_RUN_SUBSTEPS;

fn run(name: &str, duration_s: f64) -> LegReport {
    let loaded = Scenario::load(name).expect("scenario");
    let mut sim = LegSim::new(&loaded).expect("sim");
    sim.run(duration_s, &mut ()).expect("run")
}

const TEN_STRIDES_S: f64 = 16.0;

#[test]
fn gait_training_tracks_within_a_degree_over_ten_strides() {
    let r = run("gait_training", TEN_STRIDES_S);
    eprintln!("gait_training: {r:?}");
    assert!(r.finite);
    for (name, j) in &r.joints {
        assert!(j.rms_deg < 1.0, "{name}: RMS {} deg", j.rms_deg);
        assert!(j.max_deg < 3.0, "{name}: max {} deg", j.max_deg);
    }
}

#[test]
fn gait_realistic_tracks_within_three_degrees_rms() {
    let r = run("gait_realistic", TEN_STRIDES_S);
    eprintln!("gait_realistic: {r:?}");
    assert!(r.finite);
    for (name, j) in &r.joints {
        assert!(j.rms_deg < 3.0, "{name}: RMS {} deg", j.rms_deg);
    }
}

/// Ten minutes of `gait_training` at `substeps` physics steps a period (`None`: its own):
/// pressures within the supply, the co-contraction the controller adapts within 20 % of
/// where it started, both joints within a degree RMS.
fn ten_minutes_of_gait(substeps: Option<u32>) {
    let loaded = common::scenario_at("gait_training", substeps);
    let r = LegSim::new(&loaded)
        .expect("sim")
        .run(600.0, &mut ())
        .expect("run");
    assert!(r.finite);
    for (name, m) in &r.muscles {
        assert!(m.p_min_pa >= 0.0 && m.p_max_pa <= 6.0e5, "{name}: {m:?}");
    }
    let (start, end) = (r.cocontraction_pa.start, r.cocontraction_pa.end);
    eprintln!("600 s: {r:?}");
    assert!(
        (end - start).abs() <= 0.2 * start,
        "common mode {start} Pa -> {end} Pa"
    );
    for j in r.joints.values() {
        assert!(j.rms_deg < 1.0, "{j:?}");
    }
}

#[test]
fn ten_minutes_of_gait_keep_pressures_in_range_and_cocontraction_bounded() {
    ten_minutes_of_gait(Some(LONG_RUN_SUBSTEPS));
}

/// The test above at the shipped step (`LONG_RUN_SUBSTEPS` says why not in every run).
#[test]
#[ignore = "about 4 min: the shipped 64 substeps; cargo test --test leg -- --ignored"]
fn ten_minutes_of_gait_at_the_shipped_step() {
    ten_minutes_of_gait(None);
}

/// The loaded default scenario with its URDF's joint limits opened: rapier's limit
/// impacts are inelastic, and the hanging leg's rest pose sits on the knee's 0 deg limit,
/// so any passive swing would hit it.
fn without_limits(mut loaded: pma_leg::LoadedScenario) -> pma_leg::LoadedScenario {
    loaded.urdf_text = EMBEDDED_URDF
        .replace(
            r#"lower="0.0" upper="1.3963""#,
            r#"lower="-3.0" upper="3.0""#,
        )
        .replace(
            r#"lower="-0.3491" upper="0.8727""#,
            r#"lower="-3.0" upper="3.0""#,
        );
    assert_ne!(loaded.urdf_text, EMBEDDED_URDF);
    loaded
}

#[test]
fn passive_leg_with_vented_muscles_conserves_energy() {
    let mut loaded = without_limits(Scenario::load("gait_training").unwrap());
    loaded.scenario.joints.hip.damping_nm_s_per_rad = 0.0;
    loaded.scenario.joints.knee.damping_nm_s_per_rad = 0.0;
    let mut sim = LegSim::new(&loaded).unwrap();
    let vented = [0.0; 4];
    sim.step_with_commands(vented); // vent every muscle
    let rest = sim.exo().inertia().energy([0.0, 0.0], [0.0, 0.0]);
    for q0 in [[0.5, 0.6], [0.4, 0.8], [0.6, 0.0]] {
        sim.set_state(q0, [0.0, 0.0]);
        let e0 = sim.exo().energy();
        let drop = e0 - rest;
        let (mut worst, mut max_force): (f64, f64) = (0.0, 0.0);
        for _ in 0..2000 {
            let s = sim.step_with_commands(vented);
            worst = worst.max((sim.exo().energy() - e0).abs());
            max_force = s.legs[0].force_n.iter().fold(max_force, |m, f| m.max(*f));
        }
        // Vented muscles are slack (f0 < 0) except when stretched fast enough for their
        // damper to exceed |f0| + k x: then they dissipate a little, within the budget.
        eprintln!("released at {q0:?}: |E - E0| <= {worst:.4} J of {drop:.3} J, vented pull <= {max_force:.2} N");
        assert!(
            worst < 0.01 * drop,
            "released at {q0:?}: energy off by {worst} J of {drop} J (largest vented-muscle pull {max_force} N)"
        );
    }
}

/// Pressures `(flexor, extensor)` that hold a joint still against `gravity_nm` with mean
/// `p_mean`, from eq. (1) at rest: F = (f0 - k0 x) + (f1 - k1 x) p on each side and
/// r (F_flexor - F_extensor) + gravity = 0.
fn hand_pressures(
    f: &pma_leg::MuscleActuator,
    e: &pma_leg::MuscleActuator,
    q: f64,
    gravity_nm: f64,
    p_mean: f64,
) -> (f64, f64) {
    let coeff = |m: &pma_leg::MuscleActuator| {
        let x = m.geometry.contraction(q);
        let p = &m.model.as_three_element();
        (
            p.f0_n - p.k0_n_per_m * x,
            p.f1_n_per_pa - p.k1_n_per_m_pa * x,
        )
    };
    let ((af, bf), (ae, be)) = (coeff(f), coeff(e));
    let r = f.geometry.pulley_radius_m;
    assert_eq!(r, e.geometry.pulley_radius_m);
    let p_f = (-gravity_nm / r - af + ae + 2.0 * be * p_mean) / (bf + be);
    (p_f, 2.0 * p_mean - p_f)
}

#[test]
fn static_pose_is_held_at_the_hand_computed_equilibrium_pressures() {
    let loaded = Scenario::load("gait_training").unwrap();
    let mut sim = LegSim::new(&loaded).unwrap();
    let pose = [0.35, 0.5];
    sim.hold_pose(pose);
    let mut last = Vec::new();
    // 20 s: the co-contraction loop and the slow pole of the sliding surface (c2/c1 ~ 1/s)
    // settle in ~10 s; the last second is averaged.
    let settle_s = 20.0;
    let mut keep = FnRecorder(|p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>| {
        if p.t_s > settle_s {
            last.push(TrainerSample::of(p).legs[0]);
        }
    });
    sim.run(settle_s + 1.0, &mut keep).unwrap();
    let n = last.len() as f64;
    let mean_p = |i: usize| last.iter().map(|s| s.pressure_pa[i]).sum::<f64>() / n;
    let q = [
        last.iter().map(|s| s.angle_rad[0]).sum::<f64>() / n,
        last.iter().map(|s| s.angle_rad[1]).sum::<f64>() / n,
    ];
    // Held near the commanded pose (the co-contraction interference can leave up to
    // delta / (2 r) ~ 3 mrad) and still: the hand check uses the angles actually held.
    assert!(
        (q[0] - pose[0]).abs() < 0.01 && (q[1] - pose[1]).abs() < 0.01,
        "held at {q:?}"
    );
    for j in 0..2 {
        let (lo, hi) = last.iter().fold((f64::MAX, f64::MIN), |(l, h), s| {
            (l.min(s.angle_rad[j]), h.max(s.angle_rad[j]))
        });
        assert!(hi - lo < 1e-4, "joint {j} still moves by {} rad", hi - lo);
    }
    let gravity = sim.exo().inertia().gravity_torques(q[0], q[1]);
    let muscles = sim.muscles();
    for joint in 0..2 {
        let idx = |side| {
            (0..4)
                .find(|&i| muscles[i].joint == joint && muscles[i].geometry.side == side)
                .unwrap()
        };
        let (fi, ei) = (idx(Side::Flexor), idx(Side::Extensor));
        let (pf, pe) = (mean_p(fi), mean_p(ei));
        let (hf, he) = hand_pressures(
            &muscles[fi],
            &muscles[ei],
            q[joint],
            gravity[joint],
            0.5 * (pf + pe),
        );
        eprintln!("joint {joint} at {:.4} rad: flexor {pf:.0} Pa (hand {hf:.0}), extensor {pe:.0} Pa (hand {he:.0})", q[joint]);
        assert!(
            (pf - hf).abs() < 0.01 * hf,
            "joint {joint}: flexor {pf} Pa, by hand {hf} Pa"
        );
        assert!(
            (pe - he).abs() < 0.01 * he,
            "joint {joint}: extensor {pe} Pa, by hand {he} Pa"
        );
    }
}

fn tmp(dir: &std::path::Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

fn scenario_text() -> String {
    include_str!("../crates/pma-leg/models/scenarios/gait_training.toml").to_owned()
}

fn load_err(text: &str, extra_files: &[(&str, &str)]) -> String {
    let dir = common::Scratch::new("leg-load");
    for (n, t) in extra_files {
        tmp(&dir, n, t);
    }
    let path = tmp(&dir, "scenario.toml", text);
    match Scenario::load(&path).and_then(|l| LegSim::new(&l).map(|_| ())) {
        Ok(()) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_scenarios_and_urdfs_are_named_in_one_line() {
    let one_line = |e: &str| assert_eq!(e.lines().count(), 1, "{e}");
    // Missing file.
    let e = Scenario::load("/nonexistent/leg.toml")
        .unwrap_err()
        .to_string();
    one_line(&e);
    assert!(e.contains("/nonexistent/leg.toml"), "{e}");
    // Unknown field.
    let e = load_err(
        &scenario_text().replace("[gait]", "[gait]\ncadence = 3"),
        &[],
    );
    one_line(&e);
    assert!(e.contains("cadence"), "{e}");
    // A negative valve lag in the controllers' model.
    let e = load_err(
        &scenario_text().replace(
            "[control]",
            "[control]\nnominal_valve_time_constant_s = -0.02",
        ),
        &[],
    );
    one_line(&e);
    assert!(e.contains("nominal_valve_time_constant_s"), "{e}");
    // Unknown link in a muscle.
    let muscles = include_str!("../crates/pma-leg/models/muscles.toml").replacen(
        "body_link = \"thigh\"",
        "body_link = \"femur\"",
        1,
    );
    let text = format!("muscle_geometry = \"muscles.toml\"\n{}", scenario_text());
    let e = load_err(&text, &[("muscles.toml", &muscles)]);
    one_line(&e);
    assert!(e.contains("femur") && e.contains("hip_flexor"), "{e}");
    // Regression (first-hour defect 8): a duplicated muscle name was silently merged.
    let muscles = include_str!("../crates/pma-leg/models/muscles.toml").replacen(
        "name = \"knee_flexor\"",
        "name = \"hip_flexor\"",
        1,
    );
    let text = format!("muscle_geometry = \"muscles.toml\"\n{}", scenario_text());
    let e = load_err(&text, &[("muscles.toml", &muscles)]);
    one_line(&e);
    assert!(e.contains("hip_flexor") && e.contains("twice"), "{e}");
    // Malformed XML.
    let text = format!("urdf = \"leg.urdf\"\n{}", scenario_text());
    let e = load_err(
        &text,
        &[("leg.urdf", "<robot name=\"x\"><link name=\"a\"></robot>")],
    );
    one_line(&e);
    assert!(e.contains("leg.urdf"), "{e}");
    // A URDF without the knee.
    let no_knee = EMBEDDED_URDF.replace("name=\"knee\"", "name=\"ankle\"");
    let e = load_err(&text, &[("leg.urdf", &no_knee)]);
    assert!(e.contains("knee"), "{e}");
    // Unknown scenario name.
    assert!(Scenario::load("gait_jogging")
        .unwrap_err()
        .to_string()
        .contains("gait_jogging"));
}

/// Regression: a leg that diverged (`pulley_radius_m = 10`: hip RMS 3.97e31 deg) was
/// reported as a finite success. A run whose state leaves physical bounds now fails.
#[test]
fn a_leg_run_that_leaves_physical_bounds_fails() {
    let loaded = Scenario::load("gait_training").unwrap();
    let mut sim = LegSim::new(&loaded).unwrap();
    // A knee spun at 80 rad/s: no limb moves so fast.
    sim.set_state([0.2, 0.3], [0.0, 80.0]);
    let e = sim.run(4.0, &mut ()).expect_err("left physics");
    let msg = e.to_string();
    assert!(
        msg.contains("physical bounds") && msg.contains("knee"),
        "{msg}"
    );
    // A sane start runs.
    let mut sim = LegSim::new(&loaded).unwrap();
    sim.run(0.5, &mut ()).expect("a normal run");
}

/// The leg's reading channel `channel` (0-1 the encoders, 2-3 the cuff torques) reading
/// `value` from `at_s` on (a broken wire, a saturated sensor).
struct BadChannel {
    plant: pma_leg::LegPlant,
    at_s: f64,
    channel: usize,
    value: f64,
}

impl pma_loop::Backend for BadChannel {
    type Reading = PerLeg<pma_leg::LegReading>;
    type Command = PerLeg<[f64; 4]>;
    type Truth = pma_leg::TrainerState;
    type Error = pma_leg::LegError;
    fn period_s(&self) -> f64 {
        self.plant.period_s()
    }
    fn start(&mut self) -> Result<pma_loop::Started<Self::Reading, Self::Command>, Self::Error> {
        self.plant.start()
    }
    fn wait(&mut self) -> Result<u32, Self::Error> {
        self.plant.wait()
    }
    fn read(&mut self) -> Result<Self::Reading, Self::Error> {
        let mut r = self.plant.read()?;
        if self.plant.time() >= self.at_s {
            r[0][self.channel] = self.value;
        }
        Ok(r)
    }
    fn write(&mut self, c: &Self::Command) -> Result<Self::Command, Self::Error> {
        self.plant.write(c)
    }
    fn truth(&self) -> pma_leg::TrainerState {
        self.plant.truth()
    }
    fn stop(&mut self) {
        self.plant.stop();
    }
}

/// `gait_training`'s leg in `mode` under the rig's supervisor, its channel `channel`
/// reading `value` from `at_s` on, and its controllers.
fn with_bad_channel(
    mode: pma_leg::ControlMode,
    channel: usize,
    value: f64,
    at_s: f64,
) -> (
    pma_control::Supervised<BadChannel>,
    pma_leg::TrainerControllers,
) {
    let mut loaded = Scenario::load("gait_training").unwrap();
    loaded.scenario.control.mode = mode;
    let sim = LegSim::new(&loaded).unwrap();
    let (plant, controllers, limits) = sim.into_parts();
    let bad = BadChannel {
        plant,
        at_s,
        channel,
        value,
    };
    (pma_control::Supervised::new(bad, limits, None), controllers)
}

/// The leg runs under the rig's supervisor: a NaN encoder vents all four muscles and ends
/// the run as a fault naming the joint.
#[test]
fn a_nan_encoder_vents_all_four_muscles_and_ends_the_run_as_a_fault() {
    use pma_loop::Backend;
    let (mut leg, mut controllers) =
        with_bad_channel(pma_leg::ControlMode::Position, 1, f64::NAN, 1.0);
    let settings = pma_loop::LoopSettings::new(3.0).unwrap();
    let out = pma_loop::run(&mut leg, &mut controllers, &mut (), &settings).unwrap();
    match out.end {
        pma_loop::End::Fault {
            period,
            error: pma_control::Fault::SensorNan { channel },
            ..
        } => {
            assert_eq!(channel, "knee angle");
            assert!((999..=1001).contains(&period), "period {period}");
        }
        other => panic!("{other:?}"),
    }
    let set_points: Vec<f64> = leg
        .inner()
        .plant
        .muscles()
        .iter()
        .map(|m| m.set_point())
        .collect();
    assert_eq!(set_points, [0.0; 4], "every muscle vented");
    assert!(leg.inner().plant.time() < 1.01);
    let _ = leg.period_s();
}

/// In admittance mode, whose loop reads the cuffs, a cuff torque sensor beyond its full
/// scale (saturated, or a cable pulled) is a fault as an encoder out of its window is:
/// the muscles vent and the fault names the sensor.
#[test]
fn a_cuff_torque_beyond_full_scale_vents_the_muscles_and_names_the_sensor() {
    let full_scale = pma_leg::sim::CUFF_TORQUE_FULL_SCALE_NM;
    let (mut leg, mut controllers) =
        with_bad_channel(pma_leg::ControlMode::Admittance, 2, 1.5 * full_scale, 0.5);
    let settings = pma_loop::LoopSettings::new(2.0).unwrap();
    let out = pma_loop::run(&mut leg, &mut controllers, &mut (), &settings).unwrap();
    match out.end {
        pma_loop::End::Fault {
            error: pma_control::Fault::PositionOut { channel, unit, .. },
            ..
        } => assert_eq!((channel, unit), ("hip cuff torque", "N m")),
        other => panic!("{other:?}"),
    }
    assert!(leg
        .inner()
        .plant
        .muscles()
        .iter()
        .all(|m| m.set_point() == 0.0));
}

/// The cuff sensors' readings are the true torque the device puts into the limb (the
/// outputs' interaction torque) plus the sensor's bias and noise of the RMS it is given;
/// each reading draws afresh.
#[test]
fn cuff_readings_carry_the_sensors_bias_and_noise_around_the_true_torque() {
    use pma_loop::Backend;
    let mut loaded = Scenario::load("gait_training").unwrap();
    loaded.scenario.plant.cuff_sensor = pma_leg::plant::CuffSensorSettings {
        noise_rms_nm: 2.0,
        bias_nm: [1.0, -3.0],
        seed: 7,
    };
    let mut sim = LegSim::new(&loaded).unwrap();
    let plant = sim.plant_mut();
    let truth = plant.truth().legs[0].interaction_nm;
    let n = 20_000;
    let mut sum = [0.0; 2];
    let mut sq = [0.0; 2];
    for _ in 0..n {
        let r = plant.read().unwrap()[0];
        for j in 0..2 {
            let e = r[2 + j] - truth[j];
            sum[j] += e;
            sq[j] += e * e;
        }
    }
    for (j, bias) in [1.0, -3.0].iter().enumerate() {
        let mean = sum[j] / n as f64;
        let sd = (sq[j] / n as f64 - mean * mean).sqrt();
        // Four standard errors of the mean (2 / sqrt(n) = 0.014 N m); the RMS within 3 %.
        assert!((mean - bias).abs() < 0.06, "joint {j}: mean {mean}");
        assert!((sd - 2.0).abs() < 0.06, "joint {j}: sd {sd}");
    }
}

/// The leg's joint angles (rad) under 5 s of open-loop valve commands (two out-of-phase
/// sines about 3 bar per joint, 0.6 Hz at the hip and 0.9 Hz at the knee), in `substeps`
/// physics steps per period, the muscles' damping explicit or implicit; the joints' limits
/// as the URDF has them or opened.
fn open_loop_angles(substeps: u32, implicit: bool, limits: bool) -> Vec<[f64; 2]> {
    let mut loaded = Scenario::load("gait_training").unwrap();
    if !limits {
        loaded = without_limits(loaded);
    }
    loaded.scenario.physics_substeps = substeps;
    loaded.scenario.implicit_muscle_damping = implicit;
    let mut sim = LegSim::new(&loaded).unwrap();
    (1..=5000)
        .map(|k| {
            let t = f64::from(k) * 1e-3;
            let (hip, knee) = (
                1.0e5 * (std::f64::consts::TAU * 0.6 * t).sin(),
                1.0e5 * (std::f64::consts::TAU * 0.9 * t).sin(),
            );
            sim.step_with_commands([3.0e5 + hip, 3.0e5 - hip, 3.0e5 + knee, 3.0e5 - knee]);
            sim.exo().angles(0)
        })
        .collect()
}

/// Each joint's RMS distance (deg) between two runs of [`open_loop_angles`].
fn rms_apart_deg(a: &[[f64; 2]], b: &[[f64; 2]]) -> [f64; 2] {
    std::array::from_fn(|j| {
        let sum: f64 = a.iter().zip(b).map(|(x, y)| (x[j] - y[j]).powi(2)).sum();
        (sum / a.len() as f64).sqrt().to_degrees()
    })
}

/// Issue 30's lead: with the muscles' damping implicit, one physics step per period is
/// closer to 32 explicit steps than one explicit step is, and the implicit steps converge;
/// where the leg reaches its limits (the URDF's), the steps at a limit stay explicit and
/// one implicit step is still no worse than one explicit step.
#[test]
fn one_implicit_step_is_more_accurate_than_one_explicit_step() {
    for limits in [false, true] {
        let reference = open_loop_angles(32, false, limits);
        let error = |substeps, implicit| {
            rms_apart_deg(&open_loop_angles(substeps, implicit, limits), &reference)
        };
        let (implicit_1, implicit_2) = (error(1, true), error(2, true));
        let (explicit_1, explicit_2) = (error(1, false), error(2, false));
        eprintln!(
            "limits {limits}: RMS off 32 explicit steps (hip, knee deg): implicit 1 {implicit_1:.4?}, 2 {implicit_2:.4?}; explicit 1 {explicit_1:.4?}, 2 {explicit_2:.4?}"
        );
        for j in 0..2 {
            assert!(
                implicit_1[j] < explicit_1[j],
                "limits {limits}, joint {j}: implicit {} deg, explicit {} deg",
                implicit_1[j],
                explicit_1[j]
            );
            if !limits {
                assert!(
                    implicit_2[j] < 0.6 * implicit_1[j],
                    "joint {j}: implicit 2 steps {} deg against 1 step {} deg: not converging",
                    implicit_2[j],
                    implicit_1[j]
                );
            }
        }
    }
}

#[test]
fn implicit_muscle_damping_on_the_treadmill_is_refused_naming_the_field() {
    let (_, text) = pma_leg::scenario::EMBEDDED_SCENARIOS
        .iter()
        .find(|(name, _)| *name == "gait_treadmill")
        .expect("gait_treadmill");
    let text = text.replace(
        "physics_substeps = 4",
        "physics_substeps = 4\nimplicit_muscle_damping = true",
    );
    let e = Scenario::from_toml_str(&text, "t.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("implicit_muscle_damping") && e.contains("t.toml"),
        "{e}"
    );
}
