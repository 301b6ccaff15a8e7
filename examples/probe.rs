use pma_control::{AprcGains, ControllerConfig, SineReference};
use pma_sim::{run_single, PlantConfig, RunSpec};
fn main() {
    let base = PlantConfig::preset("realistic").unwrap();
    let mut lag_only = base.clone(); lag_only.sensor = PlantConfig::preset("mismatch").unwrap().sensor;
    let mut noise_only = base.clone(); noise_only.valve.time_constant_s = 0.0;
    let mut quant_only = noise_only.clone(); quant_only.sensor.noise_rms_m = 0.0;
    for (name, cfg) in [("lag", &lag_only), ("noise+quant", &noise_only), ("quant", &quant_only), ("all", &base)] {
        for bw in [100.0, 200.0, 400.0] {
            let g = AprcGains { estimator_bandwidth_rad_s: bw, ..AprcGains::PAPER };
            let n = run_single(&ControllerConfig::AprcNdo(g), cfg, &SineReference::paper(), &RunSpec::default(), None).unwrap();
            println!("{name:12} bw {bw:5} aprc-ndo RTE {:8.3} MAE {:8.2e}", n.stats.rte_percent, n.stats.mae_m);
        }
    }
}
