//! TEMPORARY probe: a scenario's servo-driven demand, per leg, and its ground figures.
use pma_leg::tools::stride_demand;
use pma_leg::Scenario;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut loaded = Scenario::load(&args[1]).expect("scenario");
    for kv in &args[3..] {
        let (k, v) = kv.split_once('=').expect("k=v");
        let v: f64 = v.parse().expect("number");
        if k == "substeps" {
            loaded.scenario.physics_substeps = v as u32;
            continue;
        }
        if k == "stride" {
            loaded.scenario.gait.stride_period_s = v;
            continue;
        }
        let t = loaded.scenario.treadmill.as_mut().expect("treadmill");
        match k {
            "speed" => t.speed_m_per_s = Some(v),
            "stiffness" => t.ankle.stiffness_nm_per_rad = v,
            "rest" => t.ankle.rest_deg = v,
            "damping" => t.ankle.damping_nm_s_per_rad = v,
            "bws" => t.bws_fraction = v,
            "fore_aft" => t.pelvis_fore_aft_n_per_m = v,
            "fore_damp" => t.pelvis_fore_aft_damping_n_s_per_m = v,
            "stride" => loaded.scenario.gait.stride_period_s = v,
            "substeps" => loaded.scenario.physics_substeps = v as u32,
            "friction" => t.contact.friction = v,
            "e" => t.contact.stiffness_n_per_m2 = v,
            _ => panic!("unknown {k}"),
        }
    }
    let d = stride_demand(&loaded, 4).expect("demand");
    let mass = loaded.scenario.treadmill.map_or(75.0, |t| t.body_mass_kg);
    for leg in 0..d.legs {
        let s: Vec<_> = d.of_leg(leg).collect();
        let r = |j: usize| {
            s.iter()
                .fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], x| {
                    [a.min(x.torque_nm[j]), b.max(x.torque_nm[j])]
                })
        };
        let (h, k) = (r(0), r(1));
        println!(
            "leg {leg}: hip {:.1}..{:.1} N m ({:.2} N m/kg), knee {:.1}..{:.1} N m ({:.2} N m/kg)",
            h[0],
            h[1],
            h[0].abs().max(h[1]) / mass,
            k[0],
            k[1],
            k[0].abs().max(k[1]) / mass
        );
    }
    println!("max servo error {:?} deg", d.max_error_deg);
    if let Some(t) = &d.treadmill {
        println!(
            "belt {:.3} m/s, belt load {:.3} vs {:.3} BW, harness fore-aft {:.0} ({:.0}..{:.0}) N, pelvis dz {:.1} mm dx {:.1} mm",
            t.belt_speed_m_s, t.mean_belt_load_bw, t.expected_belt_load_bw, t.harness_fore_aft_n.mean,
            t.harness_fore_aft_n.min, t.harness_fore_aft_n.max, 1e3 * t.pelvis_excursion_m, 1e3 * t.pelvis_fore_aft_excursion_m
        );
        for (side, f) in &t.feet {
            println!(
                "  {side}: {} strides, GRF peak {:.3} BW ({:.3}..{:.3}), rate {:.1} BW/s, stance {:.1} % (ref {:.1}), slip {:.1} mm, ankle {:.1}..{:.1}",
                f.strides, f.peak_grf_bw.mean, f.peak_grf_bw.min, f.peak_grf_bw.max, f.loading_rate_bw_s.mean,
                100.0 * f.stance_fraction.mean, 100.0 * f.reference_stance_fraction, 1e3 * f.slip_per_stride_m.mean,
                f.ankle_range_deg[0], f.ankle_range_deg[1]
            );
        }
    }
    if let Some(path) = args.get(2).filter(|p| *p != "-") {
        let mut out = String::from(
            "t,leg,phase,hip_tau,knee_tau,fz,fx,ankle_deg,hip_deg,knee_deg,px,pz,slip\n",
        );
        for s in &d.samples {
            out.push_str(&format!(
                "{:.4},{},{:.4},{:.3},{:.3},{:.2},{:.2},{:.3},{:.3},{:.3},{:.5},{:.5},{:.4}\n",
                s.t_s,
                s.leg,
                s.phase,
                s.torque_nm[0],
                s.torque_nm[1],
                s.grf_n[0],
                s.grf_n[1],
                s.ankle_rad.to_degrees(),
                s.angle_rad[0].to_degrees(),
                s.angle_rad[1].to_degrees(),
                s.pelvis_m[0],
                s.pelvis_m[1],
                s.slip_m_s
            ));
        }
        std::fs::write(path, out).expect("write");
    }
}
