use pma_control::Reference;
use pma_control::SineReference;
use pma_model::GRAVITY_M_S2;
use pma_sim::{MuscleBench, Plant, PlantConfig};
fn main() {
    let plant = PlantConfig::preset("realistic").unwrap();
    let run = |n: u32| {
        let m = plant.true_muscle();
        let mut b = MuscleBench::at_rest(&plant, 0.015)
            .unwrap()
            .with_substeps(n);
        let r = SineReference::paper();
        (1..=20000)
            .map(|k| {
                let xd = r.sample(k as f64 * 1e-3).position_m;
                let p = m
                    .static_pressure_for(plant.load.mass_kg * GRAVITY_M_S2, xd)
                    .unwrap();
                b.apply(p, 1e-3);
                b.position()
            })
            .collect::<Vec<f64>>()
    };
    let fine = run(640);
    for n in [2u32, 4, 8, 16, 32, 64] {
        let c = run(n);
        let e = c
            .iter()
            .zip(&fine)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!("substeps {n:3} err vs 640: {e:.3e}");
    }
}
