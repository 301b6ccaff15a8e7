use pma_control::{AprcGains, ChirpReference, ControllerConfig, Reference, SineReference};
use pma_sim::{run_single, PlantConfig, RunSpec, Sample};
fn stats(cfg: &ControllerConfig, plant: &str, r: &dyn Reference) -> (f64, f64, f64) {
    let plant = PlantConfig::preset(plant).unwrap();
    let mut u = Vec::new();
    let res = run_single(
        cfg,
        &plant,
        r,
        &RunSpec::default(),
        Some(&mut |s: &Sample| {
            if s.t_s > 4.0 {
                u.push(s.pressure_cmd_pa)
            }
        }),
    )
    .unwrap();
    let (mut n, mut last) = (0, 0.0f64);
    for w in u.windows(2) {
        let d = w[1] - w[0];
        if d != 0.0 {
            if last != 0.0 && d.signum() != last {
                n += 1;
            }
            last = d.signum();
        }
    }
    (
        n as f64 / 4.0,
        res.stats.rte_percent,
        res.command_variation_pa_per_s / 1e5,
    )
}
fn main() {
    for p in ["ideal", "mismatch"] {
        for a in [0.005, 0.01, 0.015, 0.02] {
            let r = SineReference {
                amplitude_m: a,
                offset_m: a,
                ..SineReference::paper()
            };
            let mut line = format!("{p:9} A {:2} mm", a * 1e3);
            for (name, c) in [
                ("aprc-ndo", ControllerConfig::AprcNdo(AprcGains::PAPER)),
                ("aprc", ControllerConfig::Aprc(AprcGains::PAPER)),
            ] {
                let (t, rte, tv) = stats(&c, p, &r);
                line += &format!(" | {name} turns {t:5.1} RTE {rte:6.3} var {tv:5.2}");
            }
            println!("{line}");
        }
        let (t, rte, tv) = stats(
            &ControllerConfig::AprcNdo(AprcGains::PAPER),
            p,
            &ChirpReference::paper(),
        );
        println!("{p:9} chirp aprc-ndo turns {t:5.1} RTE {rte:6.3} var {tv:5.2}");
    }
}
