use pma_model::{DampingMode, MuscleParams, GRAVITY_M_S2};

/// The model a model-based controller believes in: eq. (2) with the muscle parameters, the
/// mass it assumes, and the static load it expects to hold. The paper's controllers use
/// Table I and a hanging 2 kg load (`load_force_n = m g`); a muscle on an exoskeleton joint
/// sees the joint inertia reflected through its moment arm and its antagonist's pull.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NominalModel {
    /// Muscle parameters (eq. 1).
    pub muscle: MuscleParams,
    /// Assumed load mass (kg).
    pub mass_kg: f64,
    /// Static load the muscle holds (N): `m g` for the paper's hanging mass.
    pub load_force_n: f64,
    /// Cap (Pa) of the band within which the command holds instead of reversing direction
    /// (see [`NominalModel::mode_switch_band`]).
    pub mode_switch_deadband_pa: f64,
    /// Fraction of the inflation/deflation hysteresis width that the band spans.
    pub mode_switch_fraction: f64,
    /// Time constant (s) of the first-order valve lag the controller compensates; `0`
    /// (the paper) takes the pressure to equal the command. See [`NominalModel::valve_alpha`].
    pub valve_time_constant_s: f64,
}

/// Default [`NominalModel::mode_switch_deadband_pa`] (Pa).
pub const DEFAULT_MODE_SWITCH_DEADBAND_PA: f64 = 500.0;
/// Default [`NominalModel::mode_switch_fraction`].
pub const DEFAULT_MODE_SWITCH_FRACTION: f64 = 0.05;

impl NominalModel {
    /// Table I with a 2 kg load.
    pub const fn paper() -> Self {
        Self {
            muscle: MuscleParams::TABLE_I,
            mass_kg: 2.0,
            load_force_n: 2.0 * GRAVITY_M_S2,
            mode_switch_deadband_pa: DEFAULT_MODE_SWITCH_DEADBAND_PA,
            mode_switch_fraction: DEFAULT_MODE_SWITCH_FRACTION,
            valve_time_constant_s: 0.0,
        }
    }

    /// Fraction of the way from the pressure to a command held for `dt` that the nominal
    /// valve covers, `1 - exp(-dt / tau)` (the exact solution of the first-order lag);
    /// `1` without lag.
    pub fn valve_alpha(&self, dt: f64) -> f64 {
        if self.valve_time_constant_s > 0.0 {
            -(-dt / self.valve_time_constant_s).exp_m1()
        } else {
            1.0
        }
    }

    /// Band (Pa) within which a command that would reverse the pressure's direction is held
    /// instead: `min(mode_switch_deadband_pa, mode_switch_fraction * width)`, `width` the
    /// distance between the inflation and the deflation solutions (the hysteresis of eq. 1
    /// at the current velocity). Proportional to the width, so that slow and small motions
    /// stay accurate; capped, so that fast ones do not hold long. With 5 % and 500 Pa the
    /// command turns 4-6 times per period of the paper's sine at 5-20 mm amplitude (2 is
    /// the minimum), against 46-62 times for an exact inversion.
    pub fn mode_switch_band(&self, width_pa: f64) -> f64 {
        (self.mode_switch_fraction * width_pa).min(self.mode_switch_deadband_pa)
    }

    /// Drift term `f(x, xdot)` of eq. (2) (m/s^2), with `m g` generalised to the static load.
    pub fn drift(&self, x: f64, v: f64, mode: DampingMode) -> f64 {
        let (b0, _) = self.muscle.damping_coefficients(mode);
        (self.muscle.f0_n - self.load_force_n - b0 * v - self.muscle.k0_n_per_m * x) / self.mass_kg
    }

    /// Input gain `b(x, xdot)` of eq. (2) (m/s^2 per Pa).
    pub fn input_gain(&self, x: f64, v: f64, mode: DampingMode) -> f64 {
        let (_, b1) = self.muscle.damping_coefficients(mode);
        (self.muscle.f1_n_per_pa - b1 * v - self.muscle.k1_n_per_m_pa * x) / self.mass_kg
    }

    /// The input gain, kept away from zero and from the wrong sign: a fast extension can
    /// make `f1 - b1 xdot` vanish, and dividing by it would command nonsense. The floor is
    /// a tenth of the gain at rest.
    pub fn safe_input_gain(&self, x: f64, v: f64, mode: DampingMode) -> f64 {
        let floor = 0.1 * self.muscle.f1_n_per_pa / self.mass_kg;
        self.input_gain(x, v, mode).max(floor)
    }
}

impl Default for NominalModel {
    fn default() -> Self {
        Self::paper()
    }
}

/// What the controllers believe: Table I and this load mass.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct NominalSpec {
    /// Assumed load mass (kg).
    pub mass_kg: f64,
    /// See [`NominalModel::mode_switch_deadband_pa`].
    #[cfg_attr(feature = "serde", serde(default = "default_deadband"))]
    pub mode_switch_deadband_pa: f64,
    /// See [`NominalModel::mode_switch_fraction`].
    #[cfg_attr(feature = "serde", serde(default = "default_fraction"))]
    pub mode_switch_fraction: f64,
    /// Valve lag the controllers compensate (s), [`NominalModel::valve_time_constant_s`];
    /// 0 (the default, the paper) takes the pressure to equal the command.
    #[cfg_attr(feature = "serde", serde(default))]
    pub valve_time_constant_s: f64,
}

fn default_deadband() -> f64 {
    DEFAULT_MODE_SWITCH_DEADBAND_PA
}

fn default_fraction() -> f64 {
    DEFAULT_MODE_SWITCH_FRACTION
}

impl NominalSpec {
    /// Checks the assumed load and the settings; fields named as in the file's section.
    pub fn validate(&self) -> Result<(), pma_model::Invalid> {
        use pma_model::error::{non_negative, within};
        within(
            "mass_kg",
            self.mass_kg,
            f64::MIN_POSITIVE,
            pma_model::MAX_LOAD_KG,
            "must be > 0 and at most 600 kg",
        )?;
        within(
            "valve_time_constant_s",
            self.valve_time_constant_s,
            0.0,
            pma_model::MAX_VALVE_DELAY_S,
            "must be 0 to 1 s",
        )?;
        non_negative("mode_switch_deadband_pa", self.mode_switch_deadband_pa)?;
        non_negative("mode_switch_fraction", self.mode_switch_fraction)?;
        Ok(())
    }

    /// The model the controllers get: Table I (the paper uses it for every muscle) with
    /// this load and these settings.
    pub fn model(&self) -> NominalModel {
        NominalModel {
            muscle: pma_model::MuscleParams::TABLE_I,
            mass_kg: self.mass_kg,
            load_force_n: self.mass_kg * pma_model::GRAVITY_M_S2,
            mode_switch_deadband_pa: self.mode_switch_deadband_pa,
            mode_switch_fraction: self.mode_switch_fraction,
            valve_time_constant_s: self.valve_time_constant_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_pressure_makes_the_nominal_acceleration_vanish() {
        let n = NominalModel::paper();
        let x = 0.02;
        let p = n.muscle.static_pressure_for(n.load_force_n, x).unwrap();
        let a = n.drift(x, 0.0, DampingMode::Inflation)
            + n.input_gain(x, 0.0, DampingMode::Inflation) * p;
        assert!(a.abs() < 1e-9, "a = {a}");
    }
}
