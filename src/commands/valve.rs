//! `pma-exo valve`: a pressure step of a Festo muscle behind a flow-limited valve, its
//! supply and tube (`pma_model::pneumatics`): rise and fall times, peak pressure rates.
use crate::say;
use anyhow::{bail, Context, Result};
use pma_model::festo::DmspSize;
use pma_model::pneumatics::{step_response, PneumaticsSettings, StepResponse, ValveSpec};

/// `valve`'s arguments.
#[derive(clap::Args)]
pub struct Args {
    /// A shipped valve (mpye-5-1-8-hf, mpye-5-1-4, mpye-5-3-8) or a valve file (.toml).
    #[arg(default_value = "mpye-5-1-4")]
    valve: String,
    /// The muscle's size.
    #[arg(long, default_value = "dmsp-20", value_parser = size)]
    muscle: DmspSize,
    /// The muscle's nominal length (m).
    #[arg(long, default_value_t = 1.2, allow_negative_numbers = true)]
    length_m: f64,
    /// The muscle's contraction while the step runs (m); it is held there.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    contraction_m: f64,
    /// The step's high pressure (Pa gauge); it starts and ends at 0.
    #[arg(long, default_value_t = 6.0e5, allow_negative_numbers = true)]
    pressure_pa: f64,
    /// Supply pressure (Pa gauge).
    #[arg(long, default_value_t = 7.0e5, allow_negative_numbers = true)]
    supply_pa: f64,
    /// Tube length (m).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    tube_m: f64,
    /// Tube bore (m).
    #[arg(long, default_value_t = 0.006, allow_negative_numbers = true)]
    bore_m: f64,
    /// Polytropic exponent (1 isothermal .. 1.4 adiabatic).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    exponent: f64,
    /// Integration step of the outer loop (s); the pressure's own steps are at most 50 us.
    #[arg(long, default_value_t = 1e-3, allow_negative_numbers = true)]
    step_s: f64,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

fn size(s: &str) -> Result<DmspSize, String> {
    match s {
        "dmsp-10" => Ok(DmspSize::Dmsp10),
        "dmsp-20" => Ok(DmspSize::Dmsp20),
        "dmsp-40" => Ok(DmspSize::Dmsp40),
        _ => Err("expected dmsp-10, dmsp-20 or dmsp-40".into()),
    }
}

/// How long each half of the step is held (s): long enough for the slowest shipped
/// valve into the largest muscle to settle.
const HOLD_S: f64 = 1.5;

/// Runs `valve`.
pub fn run(a: Args) -> Result<i32> {
    let settings = PneumaticsSettings {
        valve: a.valve.clone(),
        supply_pressure_pa: a.supply_pa,
        tube_length_m: a.tube_m,
        tube_bore_m: a.bore_m,
        polytropic_exponent: a.exponent,
        ..PneumaticsSettings::default()
    };
    let flag = |e: pma_model::Invalid| {
        let flag = match e.name.as_ref() {
            "supply_pressure_pa" => "--supply-pa",
            "tube_length_m" => "--tube-m",
            "tube_bore_m" => "--bore-m",
            _ => "--exponent",
        };
        anyhow::anyhow!("{flag}: {e}")
    };
    settings.validate().map_err(flag)?;
    let festo = pma_model::festo::FestoMuscle::new(a.muscle, a.length_m).context("--length-m")?;
    if !(a.step_s.is_finite() && (1e-5..=1e-2).contains(&a.step_s)) {
        bail!("--step-s = {} is invalid: must be 1e-5 to 1e-2 s", a.step_s);
    }
    if !(a.pressure_pa.is_finite() && a.pressure_pa > 0.0 && a.pressure_pa <= a.supply_pa) {
        bail!(
            "--pressure-pa = {} is invalid: must be > 0 and at most the supply, --supply-pa = {}",
            a.pressure_pa,
            a.supply_pa
        );
    }
    let stroke = festo.max_contraction_m();
    if !(a.contraction_m.is_finite() && (0.0..=stroke).contains(&a.contraction_m)) {
        bail!(
            "--contraction-m = {} is invalid: must be 0 to {stroke:.3} m (the muscle's stroke)",
            a.contraction_m
        );
    }
    let spec = ValveSpec::load(&a.valve)?;
    let chamber = a.muscle.chamber(a.length_m);
    let flow = settings.flow(&spec, chamber);
    let delay = settings.transport_delay_s();
    let r = step_response(
        &flow,
        0.0,
        a.pressure_pa,
        a.contraction_m,
        HOLD_S,
        a.step_s,
        delay,
    );
    let volume_l = (chamber.volume(a.contraction_m).0 + flow.dead_volume_m3) * 1e3;
    if a.json {
        let json = serde_json::json!({
            "valve": spec.name,
            "valve_file": a.valve,
            "muscle": format!("{}-{}", a.muscle.name(), (a.length_m * 1e3).round()),
            "volume_l": volume_l,
            "supply_pa": a.supply_pa,
            "step_pa": a.pressure_pa,
            "transport_delay_s": delay,
            "step_s": a.step_s,
            "response": r,
        });
        say!("{}", serde_json::to_string(&json)?);
        return Ok(0);
    }
    print_summary(&a, &spec, volume_l, delay, &r)?;
    Ok(0)
}

fn print_summary(
    a: &Args,
    spec: &ValveSpec,
    volume_l: f64,
    delay_s: f64,
    r: &StepResponse,
) -> Result<()> {
    say!(
        "{} ({}) into a {}-{} at {:.0} mm contraction: {:.3} l with {} m of {} mm tube; supply {} bar, polytropic exponent {}",
        spec.name,
        a.valve,
        a.muscle.name(),
        (a.length_m * 1e3).round(),
        a.contraction_m * 1e3,
        volume_l,
        a.tube_m,
        a.bore_m * 1e3,
        a.supply_pa / 1e5,
        a.exponent
    );
    say!(
        "  0 -> {} bar: 10-90 % in {:.1} ms, 63 % after {:.1} ms (transport delay {:.1} ms included), peak rate {:.0} bar/s; reached {:.3} bar",
        a.pressure_pa / 1e5,
        r.rise_10_90_s * 1e3,
        r.rise_63_s * 1e3,
        delay_s * 1e3,
        r.peak_rise_rate_pa_s / 1e5,
        r.reached_pa / 1e5
    );
    say!(
        "  {} -> 0 bar: 90-10 % in {:.1} ms, peak rate {:.0} bar/s",
        a.pressure_pa / 1e5,
        r.fall_90_10_s * 1e3,
        r.peak_fall_rate_pa_s / 1e5
    );
    say!("  source: {}", spec.source);
    Ok(())
}
