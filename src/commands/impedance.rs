//! `pma-exo impedance`: what stiffness a scenario's muscle pairs reach by co-contraction,
//! and, for a leg in the air, small-perturbation tests of what impedance mode realises.
use crate::provenance::Provenance;
use crate::say;
use anyhow::Result;
use pma_leg::base::JOINT_NAMES;
use pma_leg::control::{StiffnessRange, STIFFNESS_MAX_NM_PER_RAD};
use pma_leg::tools::{probe_frequency, probe_stiffness, FrequencyProbe, ProbeAt, StiffnessProbe};
use pma_leg::{ControlMode, LegSim, MusclePair, Scenario};
use serde::Serialize;

/// `impedance`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// An embedded scenario or a scenario .toml file.
    #[arg(default_value = "gait_training")]
    scenario: String,
    /// Hip and knee flexion (deg) at which the perturbation tests hold the leg.
    #[arg(long, value_delimiter = ',', num_args = 2, default_values_t = [20.0, 30.0], allow_negative_numbers = true)]
    pose_deg: Vec<f64>,
    /// Seconds each load is held before the pose is read: several times the pair's time
    /// constant, its own damping over its stiffness (1.6 s for gait_training's hip).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    settle: f64,
    /// The mode whose stiffness the perturbation tests measure: `impedance` (the pairs'
    /// co-contraction) or `admittance` (the muscles' controllers tracking a reference the
    /// cuff torque displaces).
    #[arg(long, default_value = "impedance", value_name = "impedance|admittance")]
    mode: pma_exo::setup::Mode,
    /// Stiffness set points to test at both joints (N m/rad, comma-separated); default:
    /// three across what co-contraction reaches at the test pose.
    #[arg(long, value_delimiter = ',', value_name = "N m/rad")]
    stiffness: Vec<f64>,
    /// Also load each set point sinusoidally at these frequencies (Hz, comma-separated):
    /// the dynamic stiffness, against admittance mode's model.
    #[arg(long, value_delimiter = ',', value_name = "Hz")]
    frequencies: Vec<f64>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Share of the range at the test pose where the three set points sit.
const SET_POINTS: [f64; 3] = [0.2, 0.5, 0.8];
/// Reference samples over a stride for the range along the gait.
const STRIDE_SAMPLES: usize = 200;

/// One joint's reach and tests.
#[derive(Serialize)]
struct JointReach {
    joint: &'static str,
    /// At rest, no torque (N m/rad).
    at_rest: Option<[f64; 2]>,
    /// Reached at every sample of a stride in the air (N m/rad): the intersection.
    over_stride_in_air: Option<[f64; 2]>,
    /// At the test pose holding its gravity.
    at_pose: Option<[f64; 2]>,
    probes: Vec<StiffnessProbe>,
    /// The frequency-response tests, set point after set point.
    frequency_probes: Vec<FrequencyProbe>,
}

fn pair(r: Option<StiffnessRange>) -> Option<[f64; 2]> {
    r.map(|r| [r.min_nm_per_rad, r.max_nm_per_rad])
}

/// Runs `impedance`: every argument checked, each joint's reach and probes measured, then
/// reported.
pub fn run(a: Args) -> Result<i32> {
    let (mode, pose_deg) = checked_args(&a)?;
    let loaded = Scenario::load(&a.scenario)?;
    let sc = &loaded.scenario;
    let sim = LegSim::new(&loaded)?;
    check_pose(&sim, pose_deg)?;
    let joints = JOINT_NAMES
        .iter()
        .enumerate()
        .map(|(j, name)| measure_joint(&a, &loaded, &sim, mode, (j, name), pose_deg))
        .collect::<Result<Vec<_>>>()?;
    let provenance = Provenance {
        scenario: Some(crate::provenance::named(&a.scenario, &sc.name)),
        ..Provenance::of_this_run()
    };
    if a.json {
        let json = serde_json::json!({
            "provenance": provenance,
            "pose_deg": pose_deg,
            "mode": mode,
            "joints": joints,
        });
        say!("{}", serde_json::to_string(&json)?);
        return Ok(0);
    }
    print_reach(sc, mode, pose_deg, &joints)?;
    say!("{}", provenance.line());
    Ok(0)
}

/// The mode and the pose (deg) of `a`, every argument checked before anything runs.
fn checked_args(a: &Args) -> Result<(ControlMode, [f64; 2])> {
    if !(a.settle.is_finite() && (0.2..=30.0).contains(&a.settle)) {
        anyhow::bail!("--settle must be 0.2 to 30 s (got {})", a.settle);
    }
    let mode = a.mode.control_mode();
    if !matches!(mode, ControlMode::Impedance | ControlMode::Admittance) {
        anyhow::bail!("--mode {mode}: the perturbation tests measure a stiffness set point, which impedance and admittance modes have");
    }
    if let Some(k) = a
        .stiffness
        .iter()
        .find(|k| !pma_leg::control::stiffness_in_range(**k))
    {
        anyhow::bail!("--stiffness {k}: each set point must be > 0 and at most {STIFFNESS_MAX_NM_PER_RAD} N m/rad");
    }
    let [lo, hi] = pma_leg::tools::PROBE_FREQUENCY_RANGE_HZ;
    if let Some(f) = a
        .frequencies
        .iter()
        .find(|f| !(f.is_finite() && (lo..=hi).contains(*f)))
    {
        anyhow::bail!("--frequencies {f}: each must be {lo} to {hi} Hz");
    }
    let pose_deg = [a.pose_deg[0], a.pose_deg[1]];
    if pose_deg.iter().any(|d| !d.is_finite()) {
        anyhow::bail!("--pose-deg must be two finite angles in degrees");
    }
    Ok((mode, pose_deg))
}

/// The pose within the joints' limits, checked (in degrees) before anything runs.
fn check_pose(sim: &LegSim, pose_deg: [f64; 2]) -> Result<()> {
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        let [lo, hi] = sim.exo().limits_rad(0)[j].map(f64::to_degrees);
        if !(lo..=hi).contains(&pose_deg[j]) {
            anyhow::bail!(
                "--pose-deg: the {name} at {} deg is outside its limits, {lo:.1} to {hi:.1} deg (the URDF's)",
                pose_deg[j]
            );
        }
    }
    Ok(())
}

/// Joint `j`'s reach by co-contraction (at rest, over a stride, at the pose) and, for a
/// leg in the air, its perturbation and frequency probes at each set point.
fn measure_joint(
    a: &Args,
    loaded: &pma_leg::LoadedScenario,
    sim: &LegSim,
    mode: ControlMode,
    (j, name): (usize, &'static str),
    pose_deg: [f64; 2],
) -> Result<JointReach> {
    let sc = &loaded.scenario;
    let inertia = *sim.exo().inertia();
    let gait = sc.gait.reference()?;
    let pose_rad = pose_deg.map(f64::to_radians);
    let p = MusclePair::new(
        sim.plant().leg_muscles(0),
        j,
        sc.plant.valve.pressure_max_pa,
    )?;
    let over_stride = stride_reach(&p, &inertia, &gait, j);
    let gravity = inertia.inverse_dynamics(pose_rad, [0.0; 2], [0.0; 2])[j];
    let at_pose = p.stiffness_range(gravity, pose_rad[j]);
    let mut probes = Vec::new();
    let mut frequency_probes = Vec::new();
    if let (true, Some(r)) = (sc.treadmill.is_none(), at_pose) {
        let set_points = if a.stiffness.is_empty() {
            SET_POINTS
                .iter()
                .map(|share| r.min_nm_per_rad + share * (r.max_nm_per_rad - r.min_nm_per_rad))
                .collect()
        } else {
            a.stiffness.clone()
        };
        for k in set_points {
            let at = ProbeAt {
                mode,
                joint: j,
                stiffness_nm_per_rad: k,
                pose_rad,
            };
            probes.push(probe_stiffness(loaded, &at, a.settle)?);
            for &f in &a.frequencies {
                frequency_probes.push(probe_frequency(loaded, &at, f)?);
            }
        }
    }
    Ok(JointReach {
        joint: name,
        at_rest: pair(p.stiffness_range(0.0, 0.0)),
        over_stride_in_air: over_stride,
        at_pose: pair(at_pose),
        probes,
        frequency_probes,
    })
}

/// The text report: each joint's reach, then its probes.
fn print_reach(
    sc: &Scenario,
    mode: ControlMode,
    pose_deg: [f64; 2],
    joints: &[JointReach],
) -> Result<()> {
    let in_air = sc.treadmill.is_none();
    say!(
        "{}: joint stiffness by co-contraction (each pair's pressure sum; the valves' range 0..{:.2} bar, both muscles pulling)",
        sc.name,
        sc.plant.valve.pressure_max_pa / 1e5
    );
    let range = |r: Option<[f64; 2]>| {
        r.map_or("none".to_owned(), |[lo, hi]| {
            format!("{lo:.1}..{hi:.1} N m/rad")
        })
    };
    if in_air {
        say!(
            "  perturbation tests in {mode} mode ({})",
            if mode == ControlMode::Admittance {
                "the muscles' controllers track a reference the cuff torque displaces"
            } else {
                "the pairs' co-contraction is the spring"
            }
        );
    }
    for j in joints {
        say!(
            "  {:<5} at rest {}; at every point of a stride in the air {}; at {:.0}/{:.0} deg holding gravity {}",
            j.joint,
            range(j.at_rest),
            range(j.over_stride_in_air),
            pose_deg[0],
            pose_deg[1],
            range(j.at_pose)
        );
        for p in &j.probes {
            if p.held_by_friction {
                say!(
                    "        set {:7.2} N m/rad: the joint did not move (deflection {:.4} deg under +/-{:.3} N m): its friction ({:.2} N m) holds the load",
                    p.set_nm_per_rad,
                    p.deflection_deg,
                    p.load_nm,
                    friction_nm(sc, j.joint)
                );
                continue;
            }
            say!(
                "        set {:7.2} N m/rad: realised {:7.2} N m/rad ({:+.1} %), load +/-{:.3} N m, deflection {:.3} deg",
                p.set_nm_per_rad,
                p.realised_nm_per_rad,
                100.0 * p.error,
                p.load_nm,
                p.deflection_deg
            );
        }
        for f in &j.frequency_probes {
            let model = if f.model_magnitude_nm_per_rad.is_nan() {
                String::new()
            } else {
                format!(
                    "; admittance's law {:.2} N m/rad at {:+.1} deg ({:+.1} %)",
                    f.model_magnitude_nm_per_rad,
                    f.model_phase_deg,
                    100.0 * f.magnitude_error
                )
            };
            say!(
                "        set {:7.2} N m/rad at {:5.2} Hz: |Z| {:8.2} N m/rad at {:+.1} deg{model}",
                f.set_nm_per_rad,
                f.frequency_hz,
                f.magnitude_nm_per_rad,
                f.phase_deg
            );
        }
    }
    if !in_air {
        say!("  (no perturbation tests: they hold a leg in the air, and this scenario stands on a treadmill)");
    }
    Ok(())
}

/// The scenario's Coulomb friction on joint `name` (N m).
fn friction_nm(sc: &Scenario, name: &str) -> f64 {
    if name == "hip" {
        sc.joints.hip.friction_nm
    } else {
        sc.joints.knee.friction_nm
    }
}

/// The stiffness the pair reaches at every sample of a stride of the leg in the air (the
/// rigid leg's inverse dynamics along the reference): the intersection of the samples'.
fn stride_reach(
    p: &MusclePair,
    inertia: &pma_leg::LegInertia,
    gait: &pma_leg::gait::GaitReference,
    joint: usize,
) -> Option<[f64; 2]> {
    let t0 = gait.ramp_s() + gait.stride_period_s();
    let mut reach = [f64::NEG_INFINITY, f64::INFINITY];
    for i in 0..STRIDE_SAMPLES {
        let g = gait.sample(t0 + gait.stride_period_s() * i as f64 / STRIDE_SAMPLES as f64);
        let q = [g.hip.angle_rad, g.knee.angle_rad];
        let torque = inertia.inverse_dynamics(
            q,
            [g.hip.velocity_rad_s, g.knee.velocity_rad_s],
            [g.hip.acceleration_rad_s2, g.knee.acceleration_rad_s2],
        )[joint];
        let r = p.stiffness_range(torque, q[joint])?;
        reach = [
            reach[0].max(r.min_nm_per_rad),
            reach[1].min(r.max_nm_per_rad),
        ];
    }
    (reach[0] <= reach[1]).then_some(reach)
}
