//! A muscle relative to Table I: one factor per parameter of eq. (1).
use crate::MuscleParams;

/// Factors applied to Table I to obtain the *true* muscle (1.0 = nominal).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct MuscleScale {
    /// Factor on `f0`.
    pub f0_scale: f64,
    /// Factor on `f1`.
    pub f1_scale: f64,
    /// Factor on `k0`.
    pub k0_scale: f64,
    /// Factor on `k1`.
    pub k1_scale: f64,
    /// Factor on `b0i`.
    pub b0_inflation_scale: f64,
    /// Factor on `b1i`.
    pub b1_inflation_scale: f64,
    /// Factor on `b0d`.
    pub b0_deflation_scale: f64,
    /// Factor on `b1d`.
    pub b1_deflation_scale: f64,
}

impl Default for MuscleScale {
    fn default() -> Self {
        Self {
            f0_scale: 1.0,
            f1_scale: 1.0,
            k0_scale: 1.0,
            k1_scale: 1.0,
            b0_inflation_scale: 1.0,
            b1_inflation_scale: 1.0,
            b0_deflation_scale: 1.0,
            b1_deflation_scale: 1.0,
        }
    }
}

impl MuscleScale {
    /// Table I with these factors applied.
    pub fn apply(&self, p: MuscleParams) -> MuscleParams {
        MuscleParams {
            f0_n: p.f0_n * self.f0_scale,
            f1_n_per_pa: p.f1_n_per_pa * self.f1_scale,
            k0_n_per_m: p.k0_n_per_m * self.k0_scale,
            k1_n_per_m_pa: p.k1_n_per_m_pa * self.k1_scale,
            b0_inflation_ns_per_m: p.b0_inflation_ns_per_m * self.b0_inflation_scale,
            b1_inflation_ns_per_m_pa: p.b1_inflation_ns_per_m_pa * self.b1_inflation_scale,
            b0_deflation_ns_per_m: p.b0_deflation_ns_per_m * self.b0_deflation_scale,
            b1_deflation_ns_per_m_pa: p.b1_deflation_ns_per_m_pa * self.b1_deflation_scale,
        }
    }
}
