//! Festo DMSP fluidic muscles as they measure: the static force of a size at a pressure and
//! contraction, from a measured force map instead of Table I.
//!
//! Table I is "a similar PMA", not a DMSP-20: at 6 bar and no contraction it gives
//! `-202 + 0.00721 * 6e5 = 4.12 kN` where a DMSP-20 delivers about 1.5 kN, so a leg sized on
//! it is driven by muscles about three times stronger than the ones it is compared with.
//! This map is the measured DMSP-20-300 at 600 kPa (Martens and Boblan 2017, "Modeling the
//! static force of a Festo pneumatic muscle actuator: a new approach and a comparison to
//! existing models", Actuators 6(4):33, Appendix A1): force against strain, linear between
//! the measured points.
//!
//! Scaling, stated as assumptions: force proportional to gauge pressure at equal strain (the
//! ideal braided muscle, `F = pi r0^2 P [a (1 - eps)^2 - b]`, Tondu and Lopez 2000, IEEE
//! Control Systems 20(2)); other sizes by their rated force (Festo's maximum force, DMSP-10
//! / 20 / 40: 630 / 1500 / 6000 N) at equal strain, as Hunt's lab scales its DMSP-10 tables.
//! Below the first measured strain (1.3 %) the force is held at the first measured value.

/// A Festo DMSP size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum DmspSize {
    /// DMSP-10 (10 mm inner diameter).
    Dmsp10,
    /// DMSP-20.
    Dmsp20,
    /// DMSP-40.
    Dmsp40,
}

/// The measured DMSP-20-300 at 600 kPa: (strain, force in N), strain = contraction over
/// the 300 mm nominal length (lengths 296, 282, 267, 250, 237, 222 mm).
pub const DMSP20_600KPA: [(f64, f64); 6] = [
    (4.0 / 300.0, 1460.0),
    (18.0 / 300.0, 1004.0),
    (33.0 / 300.0, 715.0),
    (50.0 / 300.0, 443.0),
    (63.0 / 300.0, 188.0),
    (78.0 / 300.0, 0.0),
];

/// Pressure of the measured map (Pa).
pub const MAP_PRESSURE_PA: f64 = 6e5;

impl DmspSize {
    /// Every size, smallest first.
    pub const ALL: [DmspSize; 3] = [DmspSize::Dmsp10, DmspSize::Dmsp20, DmspSize::Dmsp40];

    /// Festo's maximum (rated) force (N).
    pub fn rated_force_n(self) -> f64 {
        match self {
            DmspSize::Dmsp10 => 630.0,
            DmspSize::Dmsp20 => 1500.0,
            DmspSize::Dmsp40 => 6000.0,
        }
    }

    /// Its name as Festo writes it.
    pub fn name(self) -> &'static str {
        match self {
            DmspSize::Dmsp10 => "DMSP-10",
            DmspSize::Dmsp20 => "DMSP-20",
            DmspSize::Dmsp40 => "DMSP-40",
        }
    }

    /// Static pulling force (N) at gauge `pressure_pa` and `strain` (contraction over the
    /// nominal length): zero at or past the map's last strain, never negative.
    pub fn static_force_n(self, pressure_pa: f64, strain: f64) -> f64 {
        let scale = self.rated_force_n() / DmspSize::Dmsp20.rated_force_n();
        scale * pressure_pa.max(0.0) / MAP_PRESSURE_PA * map_force(strain)
    }

    /// The largest strain at which the muscle still pulls (the map's zero crossing).
    pub fn max_strain(self) -> f64 {
        DMSP20_600KPA[DMSP20_600KPA.len() - 1].0
    }
}

/// The measured force at 600 kPa, linear between points, held below the first.
fn map_force(strain: f64) -> f64 {
    let (first, last) = (DMSP20_600KPA[0], DMSP20_600KPA[DMSP20_600KPA.len() - 1]);
    if strain.is_nan() || strain >= last.0 {
        return 0.0;
    }
    if strain <= first.0 {
        return first.1;
    }
    DMSP20_600KPA
        .windows(2)
        .find(|w| strain <= w[1].0)
        .map_or(0.0, |w| {
            let ((x0, f0), (x1, f1)) = (w[0], w[1]);
            f0 + (f1 - f0) * (strain - x0) / (x1 - x0)
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DampingMode, MuscleParams};

    #[test]
    fn the_map_reproduces_martens_and_boblans_measurements() {
        for (strain, force) in DMSP20_600KPA {
            let f = DmspSize::Dmsp20.static_force_n(6e5, strain);
            assert!((f - force).abs() < 1e-9, "{strain}: {f} vs {force}");
        }
        // Monotone: a muscle pulls less the more it has contracted.
        let mut previous = f64::INFINITY;
        for k in 0..=300 {
            let f = DmspSize::Dmsp20.static_force_n(6e5, k as f64 * 0.001);
            assert!(f <= previous && f >= 0.0, "{k}");
            previous = f;
        }
        assert_eq!(DmspSize::Dmsp20.static_force_n(6e5, 0.3), 0.0);
        assert_eq!(DmspSize::Dmsp20.static_force_n(-1e5, 0.05), 0.0);
        assert_eq!(DmspSize::Dmsp20.static_force_n(6e5, f64::NAN), 0.0);
    }

    #[test]
    fn sizes_scale_by_their_rating_and_force_by_pressure() {
        let f20 = DmspSize::Dmsp20.static_force_n(3e5, 0.1);
        assert!((DmspSize::Dmsp40.static_force_n(3e5, 0.1) - 4.0 * f20).abs() < 1e-9);
        assert!((DmspSize::Dmsp10.static_force_n(3e5, 0.1) - 0.42 * f20).abs() < 1e-9);
        assert!((DmspSize::Dmsp20.static_force_n(6e5, 0.1) - 2.0 * f20).abs() < 1e-9);
    }

    #[test]
    fn table_one_overstates_a_dmsp20_about_threefold_at_rest_length() {
        // The figure the treadmill's sizing starts from (issue 19): Table I at 6 bar and no
        // contraction against the measured DMSP-20 at its first measured strain.
        let table_one = MuscleParams::TABLE_I.force(6e5, 0.0, 0.0, DampingMode::Inflation);
        let measured = DmspSize::Dmsp20.static_force_n(6e5, 0.0);
        let ratio = table_one / measured;
        assert!((table_one - 4124.0).abs() < 5.0, "{table_one}");
        assert!((2.7..2.9).contains(&ratio), "{ratio}");
    }
}
