//! A seeded population of plants: every Table I parameter, the load, the valve lag and the
//! sensor noise drawn independently and uniformly within ranges. Plant `k` depends only on
//! the seed and `k`, so any part of a population can be drawn on its own (a shard).
use crate::StudyError;
use pma_bench::PlantConfig;
use pma_model::MuscleScale;
use pma_model::{GaussianRng, SensorParams, ValveParams};
use serde::{Deserialize, Serialize};

/// The ranges a population is drawn from (`[lo, hi]` each).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Population {
    /// Number of plants.
    pub size: usize,
    /// Seed.
    pub seed: u64,
    /// Factor on each Table I parameter, drawn independently per parameter.
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub muscle_scale: [f64; 2],
    /// Load mass (kg).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub load_kg: [f64; 2],
    /// Valve time constant (s).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub valve_lag_s: [f64; 2],
    /// Sensor noise (m RMS).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub noise_rms_m: [f64; 2],
}

/// `[lo, hi]` with `min <= lo <= hi <= max`, both finite; else the offending end.
pub(crate) fn range_ok(
    name: &'static str,
    r: [f64; 2],
    min: f64,
    max: f64,
    expected: impl Into<std::borrow::Cow<'static, str>>,
) -> Result<(), StudyError> {
    if r[0].is_finite() && r[1].is_finite() && r[0] >= min && r[1] >= r[0] && r[1] <= max {
        Ok(())
    } else {
        Err(StudyError::from(pma_model::Invalid::new(
            name,
            if r[0] < min || !r[0].is_finite() {
                r[0]
            } else {
                r[1]
            },
            expected,
        )))
    }
}

/// Largest population: a sweep holds every run in memory before it starts.
pub const MAX_POPULATION: usize = 100_000;

impl Population {
    /// Checks the size and the ranges (each within what the plant files accept).
    pub fn validate(&self) -> Result<(), StudyError> {
        if !(1..=MAX_POPULATION).contains(&self.size) {
            return Err(StudyError::from(pma_model::Invalid::new(
                "population.size",
                self.size as f64,
                "must be 1 to 100000 (split larger studies into several sweeps)",
            )));
        }
        range_ok(
            "population.muscle_scale",
            self.muscle_scale,
            f64::MIN_POSITIVE,
            pma_model::MAX_FACTOR_ON_TABLE_I,
            "must be [lo, hi] with 0 < lo <= hi <= 100",
        )?;
        range_ok(
            "population.load_kg",
            self.load_kg,
            f64::MIN_POSITIVE,
            pma_model::MAX_LOAD_KG,
            "must be [lo, hi] kg with 0 < lo <= hi <= 600",
        )?;
        range_ok(
            "population.valve_lag_s",
            self.valve_lag_s,
            0.0,
            pma_model::MAX_VALVE_DELAY_S,
            "must be [lo, hi] s with 0 <= lo <= hi <= 1",
        )?;
        range_ok(
            "population.noise_rms_m",
            self.noise_rms_m,
            0.0,
            1e-2,
            "must be [lo, hi] m with 0 <= lo <= hi <= 0.01",
        )
    }

    /// Plant `k`: the `mismatch` preset's controller model (Table I, 2 kg) over a muscle,
    /// load, valve and sensor drawn from the ranges; the sensor is the rig's 16-bit,
    /// 0-150 mm one.
    pub fn plant(&self, k: usize) -> Result<PlantConfig, StudyError> {
        let mut rng = GaussianRng::new(
            self.seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(k as u64),
        );
        let mut draw = |r: [f64; 2]| rng.between(r[0], r[1]);
        let s = self.muscle_scale;
        let muscle = MuscleScale {
            f0_scale: draw(s),
            f1_scale: draw(s),
            k0_scale: draw(s),
            k1_scale: draw(s),
            b0_inflation_scale: draw(s),
            b1_inflation_scale: draw(s),
            b0_deflation_scale: draw(s),
            b1_deflation_scale: draw(s),
        };
        let mut plant = PlantConfig::preset("mismatch")?;
        plant.name = format!("population-{k}");
        plant.description = format!("plant {k} of a population (seed {})", self.seed);
        plant.muscle = muscle;
        plant.load = pma_model::LoadProfile::constant(draw(self.load_kg));
        plant.valve = ValveParams::ideal().with_lag(draw(self.valve_lag_s));
        plant.sensor = SensorParams {
            range_min_m: -0.05,
            range_max_m: 0.10,
            resolution_bits: 16,
            noise_rms_m: draw(self.noise_rms_m),
            seed: self.seed.wrapping_add(k as u64),
        };
        plant.validate()?;
        Ok(plant)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pop() -> Population {
        Population {
            size: 200,
            seed: 1,
            muscle_scale: [0.8, 1.2],
            load_kg: [1.0, 5.0],
            valve_lag_s: [0.0, 0.03],
            noise_rms_m: [0.0, 20e-6],
        }
    }

    #[test]
    fn a_plant_depends_on_its_index_only_and_stays_in_range() {
        let p = pop();
        assert_eq!(p.plant(17).unwrap(), p.plant(17).unwrap());
        assert_ne!(p.plant(17).unwrap(), p.plant(18).unwrap());
        for k in 0..p.size {
            let c = p.plant(k).unwrap();
            let m = c.muscle;
            for f in [m.f0_scale, m.k0_scale, m.b1_deflation_scale] {
                assert!((0.8..=1.2).contains(&f), "{f}");
            }
            assert!((1.0..=5.0).contains(&c.load.mass_kg));
            assert!((0.0..=0.03).contains(&c.valve.time_constant_s));
        }
    }
}
