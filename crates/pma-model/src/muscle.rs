use crate::error::{finite, non_negative, positive, within, Invalid};

/// Largest factor between any parameter of a muscle and Table I's: Festo's muscles span a
/// factor of 10 in force from the DMSP-10 to the DMSP-40; beyond 100 a parameter set is a
/// typo, not a muscle.
pub const MAX_FACTOR_ON_TABLE_I: f64 = 100.0;

/// Which damping coefficients of eq. (1) apply: the muscle dissipates differently while it
/// is being inflated and while it is being deflated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum DampingMode {
    /// Pressure rising: `b0i`, `b1i`.
    #[default]
    Inflation,
    /// Pressure falling: `b0d`, `b1d`.
    Deflation,
}

impl DampingMode {
    /// Mode after a pressure change of `dp` Pa: a rise inflates, a fall deflates, and an
    /// unchanged pressure keeps the previous mode (the bladder does not switch by itself).
    pub fn after_change(self, dp: f64) -> Self {
        if dp > 0.0 {
            DampingMode::Inflation
        } else if dp < 0.0 {
            DampingMode::Deflation
        } else {
            self
        }
    }
}

/// Parameters of the three-element model, eq. (1) of Cao et al. 2020:
/// `F = f0 + f1 P - (k0 + k1 P) x - (b0 + b1 P) xdot`.
///
/// Table I of the paper is garbled in its text extraction (labels `k01, k02, k11, k12`).
/// The reading used here, and the one under which a 2 kg load needs 0.3..1.1 bar for
/// 0..30 mm of contraction, is `k0 = k01 = 18063 N/m` and `k1 = k02 = 0.01051 N/(m Pa)`;
/// the row `k11, k12` is ignored.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct MuscleParams {
    /// Contractile force offset `f0` (N).
    pub f0_n: f64,
    /// Contractile force per pascal `f1` (N/Pa).
    pub f1_n_per_pa: f64,
    /// Spring coefficient offset `k0` (N/m).
    pub k0_n_per_m: f64,
    /// Spring coefficient per pascal `k1` (N/(m Pa)).
    pub k1_n_per_m_pa: f64,
    /// Damping offset while inflating `b0i` (N s/m).
    pub b0_inflation_ns_per_m: f64,
    /// Damping per pascal while inflating `b1i` (N s/(m Pa)).
    pub b1_inflation_ns_per_m_pa: f64,
    /// Damping offset while deflating `b0d` (N s/m).
    pub b0_deflation_ns_per_m: f64,
    /// Damping per pascal while deflating `b1d` (N s/(m Pa)).
    pub b1_deflation_ns_per_m_pa: f64,
}

impl MuscleParams {
    /// Table I of Cao et al. 2020 (identified by Zhu et al. 2017 on a similar Festo muscle),
    /// read as documented on the struct.
    pub const TABLE_I: MuscleParams = MuscleParams {
        f0_n: -202.32,
        f1_n_per_pa: 0.00721,
        k0_n_per_m: 18063.0,
        k1_n_per_m_pa: 0.01051,
        b0_inflation_ns_per_m: 6435.31,
        b1_inflation_ns_per_m_pa: 0.10023,
        b0_deflation_ns_per_m: 2522.01,
        b1_deflation_ns_per_m_pa: 0.00321,
    };

    /// Checks that every coefficient is finite and that the muscle pulls harder with more
    /// pressure (`f1 > 0`) and resists motion (`k0 >= 0`, `b0i`, `b0d` > 0).
    pub fn validate(&self) -> Result<(), Invalid> {
        finite("f0_n", self.f0_n)?;
        positive("f1_n_per_pa", self.f1_n_per_pa)?;
        // Zero is a muscle whose stiffness is all pressure's (a Festo map's fit).
        non_negative("k0_n_per_m", self.k0_n_per_m)?;
        finite("k1_n_per_m_pa", self.k1_n_per_m_pa)?;
        positive("b0_inflation_ns_per_m", self.b0_inflation_ns_per_m)?;
        finite("b1_inflation_ns_per_m_pa", self.b1_inflation_ns_per_m_pa)?;
        positive("b0_deflation_ns_per_m", self.b0_deflation_ns_per_m)?;
        finite("b1_deflation_ns_per_m_pa", self.b1_deflation_ns_per_m_pa)?;
        let t = Self::TABLE_I;
        for (name, value, table) in [
            ("f0_n", self.f0_n, t.f0_n),
            ("f1_n_per_pa", self.f1_n_per_pa, t.f1_n_per_pa),
            ("k0_n_per_m", self.k0_n_per_m, t.k0_n_per_m),
            ("k1_n_per_m_pa", self.k1_n_per_m_pa, t.k1_n_per_m_pa),
            (
                "b0_inflation_ns_per_m",
                self.b0_inflation_ns_per_m,
                t.b0_inflation_ns_per_m,
            ),
            (
                "b1_inflation_ns_per_m_pa",
                self.b1_inflation_ns_per_m_pa,
                t.b1_inflation_ns_per_m_pa,
            ),
            (
                "b0_deflation_ns_per_m",
                self.b0_deflation_ns_per_m,
                t.b0_deflation_ns_per_m,
            ),
            (
                "b1_deflation_ns_per_m_pa",
                self.b1_deflation_ns_per_m_pa,
                t.b1_deflation_ns_per_m_pa,
            ),
        ] {
            let bound = MAX_FACTOR_ON_TABLE_I * table.abs();
            within(
                name,
                value,
                -bound,
                bound,
                "must be within 100 times Table I's magnitude (Festo's muscles span a factor of 10 in force, DMSP-10 to DMSP-40)",
            )?;
        }
        Ok(())
    }

    /// Damping offset and per-pascal slope `(b0, b1)` for a mode.
    pub fn damping_coefficients(&self, mode: DampingMode) -> (f64, f64) {
        match mode {
            DampingMode::Inflation => (self.b0_inflation_ns_per_m, self.b1_inflation_ns_per_m_pa),
            DampingMode::Deflation => (self.b0_deflation_ns_per_m, self.b1_deflation_ns_per_m_pa),
        }
    }

    /// Damping `b(P)` (N s/m).
    pub fn damping(&self, pressure_pa: f64, mode: DampingMode) -> f64 {
        let (b0, b1) = self.damping_coefficients(mode);
        b0 + b1 * pressure_pa
    }

    /// Spring coefficient `k(P)` (N/m).
    pub fn stiffness(&self, pressure_pa: f64) -> f64 {
        self.k0_n_per_m + self.k1_n_per_m_pa * pressure_pa
    }

    /// Contractile force `f(P)` (N).
    pub fn contractile_force(&self, pressure_pa: f64) -> f64 {
        self.f0_n + self.f1_n_per_pa * pressure_pa
    }

    /// Eq. (1) force without the slack clamp: may be negative, which a real muscle cannot
    /// produce. Controllers' nominal models use this form.
    pub fn force_unclamped(
        &self,
        pressure_pa: f64,
        x_m: f64,
        v_m_s: f64,
        mode: DampingMode,
    ) -> f64 {
        self.contractile_force(pressure_pa)
            - self.stiffness(pressure_pa) * x_m
            - self.damping(pressure_pa, mode) * v_m_s
    }

    /// Pulling force of the muscle (N): eq. (1) clamped at zero, since a slack muscle
    /// cannot push.
    pub fn force(&self, pressure_pa: f64, x_m: f64, v_m_s: f64, mode: DampingMode) -> f64 {
        self.force_unclamped(pressure_pa, x_m, v_m_s, mode).max(0.0)
    }

    /// Pressure (Pa) at which the muscle holds `load_n` newtons at rest at contraction
    /// `x_m`: the static equilibrium of eq. (1). `None` where the pressure has no effect
    /// on the force (`f1 = k1 x`).
    pub fn static_pressure_for(&self, load_n: f64, x_m: f64) -> Option<f64> {
        let gain = self.f1_n_per_pa - self.k1_n_per_m_pa * x_m;
        if gain.abs() < f64::EPSILON {
            return None;
        }
        Some((load_n - self.f0_n + self.k0_n_per_m * x_m) / gain)
    }

    /// Contraction (m) at which the muscle at pressure `pressure_pa` holds `load_n` at
    /// rest: `F(P, x, 0) = load` solved for `x`; `None` if the stiffness vanishes.
    pub fn static_contraction_for(&self, load_n: f64, pressure_pa: f64) -> Option<f64> {
        let stiffness = self.stiffness(pressure_pa);
        if stiffness.abs() < f64::EPSILON {
            return None;
        }
        Some((self.contractile_force(pressure_pa) - load_n) / stiffness)
    }
}

/// What a muscle's force is: eq. (1) with its parameters, or a Festo size as measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MuscleModel {
    /// Eq. (1) (Table I, or Table I with factors).
    ThreeElement(MuscleParams),
    /// A Festo DMSP's measured static force with a scaled damping.
    Festo(crate::festo::FestoMuscle),
}

impl MuscleModel {
    /// The muscle's air space, for a flow-limited valve: a Festo size's own, or for an
    /// eq. (1) muscle the paper's rig muscle Table I was identified on, a DMSP-20-200
    /// (Cao et al. 2020, Sec. IV-A).
    pub fn chamber(&self) -> crate::Chamber {
        match self {
            MuscleModel::ThreeElement(_) => {
                crate::festo::DmspSize::Dmsp20.chamber(crate::festo::TABLE_I_REST_LENGTH_M)
            }
            MuscleModel::Festo(m) => m.size.chamber(m.rest_length_m),
        }
    }

    /// Force without the slack clamp (N): negative means slack.
    pub fn force_unclamped(
        &self,
        pressure_pa: f64,
        x_m: f64,
        v_m_s: f64,
        mode: DampingMode,
    ) -> f64 {
        match self {
            MuscleModel::ThreeElement(p) => p.force_unclamped(pressure_pa, x_m, v_m_s, mode),
            MuscleModel::Festo(m) => m.force_unclamped(pressure_pa, x_m, v_m_s, mode),
        }
    }

    /// Damping `b(P)` (N s/m): the force's slope against the contraction rate, the same
    /// at every rate (both models are affine in it).
    pub fn damping(&self, pressure_pa: f64, mode: DampingMode) -> f64 {
        match self {
            MuscleModel::ThreeElement(p) => p.damping(pressure_pa, mode),
            MuscleModel::Festo(m) => m.damping(pressure_pa, mode),
        }
    }

    /// The muscle in eq. (1)'s form: its own parameters, or the Festo map's fit
    /// ([`crate::festo::FestoMuscle::three_element_fit`]).
    pub fn as_three_element(&self) -> MuscleParams {
        match self {
            MuscleModel::ThreeElement(p) => *p,
            MuscleModel::Festo(m) => m.three_element_fit(),
        }
    }
}

impl Default for MuscleParams {
    fn default() -> Self {
        Self::TABLE_I
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_i_reading_gives_the_design_pressure_range_for_2kg() {
        let m = MuscleParams::TABLE_I;
        let w = 2.0 * crate::GRAVITY_M_S2;
        let p0 = m.static_pressure_for(w, 0.0).unwrap();
        let p30 = m.static_pressure_for(w, 0.030).unwrap();
        assert!((0.25e5..0.35e5).contains(&p0), "p(0 mm) = {p0}");
        assert!((1.0e5..1.2e5).contains(&p30), "p(30 mm) = {p30}");
    }

    #[test]
    fn static_contraction_inverts_static_pressure() {
        let m = MuscleParams::TABLE_I;
        for &x in &[-0.012, 0.0, 0.02] {
            let p = m.static_pressure_for(20.0, x).unwrap();
            let back = m.static_contraction_for(20.0, p).unwrap();
            assert!((back - x).abs() < 1e-12, "{x} -> {p} Pa -> {back}");
        }
    }

    #[test]
    fn static_pressure_is_an_equilibrium_of_eq1() {
        let m = MuscleParams::TABLE_I;
        for &x in &[0.0, 0.01, 0.02, 0.04] {
            let p = m.static_pressure_for(35.0, x).unwrap();
            let f = m.force(p, x, 0.0, DampingMode::Inflation);
            assert!((f - 35.0).abs() < 1e-9, "x={x}: F={f}");
        }
    }

    #[test]
    fn slack_muscle_does_not_push() {
        let m = MuscleParams::TABLE_I;
        assert!(m.force_unclamped(0.0, 0.02, 0.0, DampingMode::Inflation) < 0.0);
        assert_eq!(m.force(0.0, 0.02, 0.0, DampingMode::Inflation), 0.0);
    }

    #[test]
    fn damping_mode_follows_pressure_rate_and_holds_when_flat() {
        let m = DampingMode::Inflation;
        assert_eq!(m.after_change(-1.0), DampingMode::Deflation);
        assert_eq!(
            DampingMode::Deflation.after_change(0.0),
            DampingMode::Deflation
        );
        assert_eq!(
            DampingMode::Deflation.after_change(2.0),
            DampingMode::Inflation
        );
    }

    #[test]
    fn validate_rejects_nan_and_non_pulling_muscle() {
        let mut m = MuscleParams::TABLE_I;
        m.k0_n_per_m = f64::NAN;
        assert!(matches!(m.validate(), Err(e) if e.name == "k0_n_per_m"));
        let mut m = MuscleParams::TABLE_I;
        m.f1_n_per_pa = -1.0;
        assert!(m.validate().is_err());
        assert!(MuscleParams::TABLE_I.validate().is_ok());
    }
}
