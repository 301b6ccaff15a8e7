use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Seeded random source of the simulations: xoshiro256++ (`rand_xoshiro`) with
/// `rand_distr`'s standard normal (ziggurat). Both are portable, value-stable
/// implementations, so a run is reproducible from its seed on every platform.
#[derive(Debug, Clone)]
pub struct GaussianRng {
    rng: Xoshiro256PlusPlus,
}

impl GaussianRng {
    /// A generator from a 64-bit seed (expanded by `seed_from_u64`).
    pub fn new(seed: u64) -> Self {
        Self {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
        }
    }

    /// Uniform in `(0, 1]`.
    pub fn uniform(&mut self) -> f64 {
        1.0 - self.rng.random::<f64>()
    }

    /// Uniform in `[lo, hi]`.
    pub fn between(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.rng.random::<f64>()
    }

    /// Standard normal sample.
    pub fn standard_normal(&mut self) -> f64 {
        StandardNormal.sample(&mut self.rng)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_samples_have_unit_variance_and_zero_mean() {
        let mut g = GaussianRng::new(7);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let z = g.standard_normal();
            s += z;
            s2 += z * z;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.01, "var {var}");
    }

    #[test]
    fn same_seed_same_sequence() {
        let mut a = GaussianRng::new(42);
        let mut b = GaussianRng::new(42);
        for _ in 0..10 {
            assert_eq!(a.standard_normal(), b.standard_normal());
        }
    }
}
