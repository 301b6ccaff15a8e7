//! Runs every controller on every plant preset with the paper's sine and prints the metrics.
use pma_bench::{run_single, PlantConfig, RunSpec, PRESET_NAMES};
use pma_control::{ChirpReference, ControllerKind, Reference, SineReference};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let refs: [(&str, &dyn Reference); 2] = [
        ("sine", &SineReference::paper()),
        ("chirp", &ChirpReference::paper()),
    ];
    for (rname, r) in refs {
        for plant in PRESET_NAMES {
            let cfg = PlantConfig::preset(plant)?;
            for kind in ControllerKind::ALL {
                let res = run_single(
                    &kind.default_config(),
                    &cfg,
                    r,
                    &RunSpec::default(),
                    &mut (),
                )?;
                println!(
                    "{rname:6} {plant:10} {:9} MAE {:9.3e} IAE {:9.3e} RTE {:7.3} % rtf {:8.0}",
                    kind.as_str(),
                    res.stats.mae_m,
                    res.stats.iae_m,
                    res.stats.rte_percent,
                    res.real_time_factor
                );
            }
        }
    }
    Ok(())
}
