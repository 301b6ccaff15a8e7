use crate::error::{check, finite, non_negative, within, Invalid};
use crate::GaussianRng;

/// Displacement sensor: measuring range, A/D resolution and white noise. The paper's rig
/// uses a GA-75 (0-150 mm) read by a 16-bit board.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SensorParams {
    /// Lowest measurable contraction (m); readings saturate here.
    pub range_min_m: f64,
    /// Highest measurable contraction (m).
    pub range_max_m: f64,
    /// A/D resolution over the range (bits); `0` for a continuous reading.
    #[cfg_attr(feature = "serde", serde(default))]
    pub resolution_bits: u32,
    /// RMS of additive white Gaussian noise (m).
    #[cfg_attr(feature = "serde", serde(default))]
    pub noise_rms_m: f64,
    /// Seed of the noise generator.
    #[cfg_attr(feature = "serde", serde(default))]
    pub seed: u64,
}

impl SensorParams {
    /// A perfect sensor: no noise, no quantisation, a range far wider than the muscle's.
    pub const fn ideal() -> Self {
        Self {
            range_min_m: -1.0,
            range_max_m: 1.0,
            resolution_bits: 0,
            noise_rms_m: 0.0,
            seed: 0,
        }
    }

    /// Checks finite values, a non-empty range and at most 32 bits.
    pub fn validate(&self) -> Result<(), Invalid> {
        finite("range_min_m", self.range_min_m)?;
        finite("range_max_m", self.range_max_m)?;
        check(
            self.range_max_m > self.range_min_m,
            "range_max_m",
            self.range_max_m,
            "must exceed range_min_m",
        )?;
        non_negative("noise_rms_m", self.noise_rms_m)?;
        within(
            "noise_rms_m",
            self.noise_rms_m,
            0.0,
            1e-2,
            "must be 0 to 0.01 RMS in the sensor's unit (m, or rad for an encoder): sensor noise is micrometres or millidegrees",
        )?;
        check(
            self.resolution_bits <= 32,
            "resolution_bits",
            f64::from(self.resolution_bits),
            "must be 0 to 32",
        )?;
        Ok(())
    }

    /// Quantisation step (m), or 0 for a continuous reading.
    pub fn lsb_m(&self) -> f64 {
        if self.resolution_bits == 0 {
            0.0
        } else {
            (self.range_max_m - self.range_min_m) / ((1u64 << self.resolution_bits) - 1) as f64
        }
    }
}

impl Default for SensorParams {
    fn default() -> Self {
        Self::ideal()
    }
}

/// A sensor instance with its own noise stream.
#[derive(Debug, Clone)]
pub struct PositionSensor {
    params: SensorParams,
    rng: GaussianRng,
    lsb_m: f64,
}

impl PositionSensor {
    /// A sensor from validated parameters.
    pub fn new(params: SensorParams) -> Result<Self, Invalid> {
        params.validate()?;
        Ok(Self {
            params,
            rng: GaussianRng::new(params.seed),
            lsb_m: params.lsb_m(),
        })
    }

    /// Parameters.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    /// Reading (m) of a true contraction: noise added, clamped to the range (an A/D
    /// saturates), then rounded to the nearest code.
    pub fn measure(&mut self, true_x_m: f64) -> f64 {
        let noisy = if self.params.noise_rms_m > 0.0 {
            true_x_m + self.params.noise_rms_m * self.rng.standard_normal()
        } else {
            true_x_m
        };
        let clamped = noisy.clamp(self.params.range_min_m, self.params.range_max_m);
        if self.lsb_m > 0.0 {
            let code = ((clamped - self.params.range_min_m) / self.lsb_m).round();
            self.params.range_min_m + code * self.lsb_m
        } else {
            clamped
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sixteen_bits_over_150mm_quantise_to_2_3_um() {
        let p = SensorParams {
            range_min_m: 0.0,
            range_max_m: 0.150,
            resolution_bits: 16,
            noise_rms_m: 0.0,
            seed: 0,
        };
        let mut s = PositionSensor::new(p).unwrap();
        let lsb = p.lsb_m();
        assert!((lsb - 2.289e-6).abs() < 1e-9);
        let r = s.measure(0.0123456);
        assert!((r - 0.0123456).abs() <= lsb / 2.0 + 1e-15);
        assert!(((r / lsb) - (r / lsb).round()).abs() < 1e-6);
        assert_eq!(s.measure(0.2), 0.150);
    }

    #[test]
    fn noise_has_the_configured_rms() {
        let p = SensorParams {
            noise_rms_m: 20e-6,
            seed: 3,
            ..SensorParams::ideal()
        };
        let mut s = PositionSensor::new(p).unwrap();
        let n = 50_000;
        let ms: f64 = (0..n)
            .map(|_| (s.measure(0.01) - 0.01).powi(2))
            .sum::<f64>()
            / n as f64;
        assert!((ms.sqrt() - 20e-6).abs() < 0.5e-6, "rms {}", ms.sqrt());
    }
}
