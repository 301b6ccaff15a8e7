//! TEMPORARY probe: both legs servo-driven on the belt; prints per-leg demands and GRF.
use pma_leg::config::JointSettings;
use pma_leg::gait::{GaitReference, GaitSpeed};
use pma_leg::ground::TreadmillSettings;
use pma_leg::{Exoskeleton, PerLeg};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let legs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let bws: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.3);
    let stiffness: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(100.0);
    let text = include_str!("../models/exo_trainer.urdf");
    let j = JointSettings {
        damping_nm_s_per_rad: 0.5,
        friction_nm: 0.0,
    };
    let mut t = TreadmillSettings::new(bws, 75.0);
    t.speed_m_per_s = args.get(5).and_then(|s| s.parse().ok());
    t.legs = legs;
    t.ankle.stiffness_nm_per_rad = stiffness;
    t.ankle.rest_deg = args.get(6).and_then(|s| s.parse().ok()).unwrap_or(0.0);
    let gait = GaitReference::normative(GaitSpeed::Slow, 1.6, 1.6).unwrap();
    let mut exo = Exoskeleton::on_treadmill(text, "exo_trainer.urdf", [j, j], 1e-3, 1, &t).unwrap();
    if t.speed_m_per_s.is_none() {
        exo.belt_at_reference_speed(&gait);
    }
    exo.ramp_belt(gait.ramp_s());
    if legs == 1 {
        exo.add_other_leg(gait);
    }
    exo.rest_on_belt();
    let gaits: Vec<GaitReference> = (0..legs).map(|l| gait.for_leg(l)).collect();
    let v = exo.ground().unwrap().settings().belt_speed_m_s();
    let mass = 75.0;
    eprintln!(
        "belt {v:.3} m/s, system {:.1} kg",
        exo.ground().unwrap().total_mass_kg()
    );
    let (k, c) = (20000.0, 150.0);
    let periods = (1.6 * 8.0 / 1e-3) as usize;
    let start = (1.6 * 3.0 / 1e-3) as usize;
    let mut peak = vec![[0.0f64; 4]; legs]; // hip min, hip max, knee min, knee max
    let mut grf_peak = vec![0.0f64; legs];
    let mut rows = Vec::new();
    for p in 0..periods {
        let t0 = p as f64 * 1e-3;
        let mut sum = vec![[0.0; 2]; legs];
        exo.step(|e, _| {
            PerLeg::from_fn(legs, |l| {
                let g = gaits[l].sample(t0);
                let (q, qd) = (e.angles(l), e.velocities(l));
                let tau = [
                    k * (g.hip.angle_rad - q[0]) + c * (g.hip.velocity_rad_s - qd[0]),
                    k * (g.knee.angle_rad - q[1]) + c * (g.knee.velocity_rad_s - qd[1]),
                ];
                sum[l] = tau;
                tau
            })
        });
        let r = exo.ground_reaction().unwrap();
        if p >= start {
            for l in 0..legs {
                let s = sum[l];
                peak[l][0] = peak[l][0].min(s[0]);
                peak[l][1] = peak[l][1].max(s[0]);
                peak[l][2] = peak[l][2].min(s[1]);
                peak[l][3] = peak[l][3].max(s[1]);
                grf_peak[l] = grf_peak[l].max(r.feet[l].vertical_n);
            }
            let phase = gaits[0].phase(t0 + 1e-3);
            let mut row = vec![t0 + 1e-3, phase];
            for l in 0..legs {
                let a = exo.ankle(l).map_or(f64::NAN, |a| a.0.to_degrees());
                let q = exo.angles(l);
                row.extend([
                    sum[l][0],
                    sum[l][1],
                    r.feet[l].vertical_n,
                    r.feet[l].fore_aft_n,
                    r.feet[l].slip_m_s,
                    a,
                    q[0].to_degrees(),
                    q[1].to_degrees(),
                ]);
            }
            row.extend([
                r.contralateral_n,
                r.support_n,
                r.harness_fore_aft_n,
                exo.pelvis_position_m().unwrap()[0],
                exo.pelvis_position_m().unwrap()[1],
            ]);
            rows.push(row);
        }
    }
    let bw = mass * 9.80665;
    for l in 0..legs {
        println!(
            "leg {l}: hip {:.1}..{:.1} N m ({:.2} N m/kg), knee {:.1}..{:.1} N m ({:.2} N m/kg), GRF peak {:.2} BW",
            peak[l][0], peak[l][1], peak[l][0].abs().max(peak[l][1]) / mass,
            peak[l][2], peak[l][3], peak[l][2].abs().max(peak[l][3]) / mass,
            grf_peak[l] / bw
        );
    }
    if let Some(path) = args.get(4) {
        let mut out = String::new();
        for r in rows {
            out.push_str(
                &r.iter()
                    .map(|v| format!("{v:.5}"))
                    .collect::<Vec<_>>()
                    .join(","),
            );
            out.push('\n');
        }
        std::fs::write(path, out).unwrap();
    }
}
