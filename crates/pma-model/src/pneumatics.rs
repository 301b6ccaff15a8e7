//! Pneumatics a real valve delivers: a proportional valve as a flow-limited orifice (ISO
//! 6358), the supply, the muscle's volume as it contracts, the tube's volume and transport
//! delay, and the pressure as a state of each muscle.
//!
//! The valve regulates pressure: its spool opens in proportion to the pressure error
//! over a proportional band (a Festo VPPM regulates this way on its own pressure sensor;
//! an MPYE 5/3 flow valve does under a lab's pressure loop on a sensor at the muscle) and
//! follows its set point with the spool's first-order lag. The flow through the opening is
//! ISO 6358's (Sanville's form; Beater, *Pneumatic Drives*, Springer 2007, eq. 5.1):
//!
//! - choked, `p2 / p1 <= b`: `m_dot = C p1 rho0 sqrt(T0 / T1)`;
//! - subsonic: `m_dot = C p1 rho0 sqrt(T0 / T1) sqrt(1 - ((p2 / p1 - b) / (1 - b))^2)`;
//! - above `p2 / p1 = 0.999` linear in the pressure difference (a laminar blend), so that
//!   the flow's slope stays finite as the pressures meet,
//!
//! from the supply into the muscle while the spool opens, from the muscle to the atmosphere
//! while it closes (`C` scaled by the opening). The muscle's air obeys the polytropic
//! filling law (Richer & Hurmuzlu, ASME JDSMC 122(3), 2000):
//!
//! `dp/dt = (n / V) (R T m_dot - p dV/dt)` (absolute pressure `p`),
//!
//! `n = 1` isothermal (the default: the braid and rubber exchange heat over a gait's
//! strokes, and it is the slower, conservative bound), up to `1.4` adiabatic. The volume
//! `V` is the muscle's, from the braid's geometry (Chou & Hannaford, IEEE TRA 12(1),
//! 1996: thread length `b = L0 / cos(theta0)`, turns `N = L0 tan(theta0) / (pi D0)`,
//! `V(L) = L (b^2 - L^2) / (4 pi N^2)`, the rest volume the cylinder `pi D0^2 L0 / 4`),
//! plus the tube's and the fittings' dead volume. The tube delays the set point by its
//! length over the speed of sound.
use crate::error::{check, within, Invalid};

/// Specific gas constant of dry air (J/(kg K)).
pub const R_AIR_J_PER_KG_K: f64 = 287.05;
/// Temperature of the air in the supply and the muscle (K): 20 °C, ISO 6358's reference.
pub const AIR_TEMPERATURE_K: f64 = 293.15;
/// Atmospheric pressure (Pa absolute): gauge pressures are above it.
pub const ATMOSPHERE_PA: f64 = 101_325.0;
/// Density of air at ISO 8778's standard reference atmosphere (ANR: 20 °C, 100 kPa, 65 %
/// relative humidity), the density ISO 6358's conductance is stated in (kg/m3).
pub const ANR_DENSITY_KG_M3: f64 = 1.185;
/// Speed of sound in air at 20 °C (m/s): a tube's transport delay is its length over it.
pub const SPEED_OF_SOUND_M_S: f64 = 343.0;
/// Pressure ratio above which the flow is blended linearly to zero (laminar).
pub const LAMINAR_RATIO: f64 = 0.999;
/// Longest internal step of the pressure's integration (s): a tenth of the fastest pressure
/// loop's time constant a shipped valve gives (about 1 ms).
pub const PRESSURE_STEP_MAX_S: f64 = 5e-5;
/// Braid angle of a Festo DMSP at rest (rad): 28.6 degrees, as coded after Chou and
/// Hannaford for a braided muscle in `Agile-and-Adaptive-Robotics/Bipedal_Robot`
/// (`BPAdiameters.m`); Festo does not publish it. With it the volume per metre of a
/// DMSP-20 is 0.31 / 0.46 / 0.58 l at 0 / 10 / 25 % contraction.
pub const DMSP_BRAID_ANGLE_RAD: f64 = 28.6 * std::f64::consts::PI / 180.0;
/// Conversion of ISO 6358's litres per second per bar (ANR) to m3/(s Pa).
pub const L_PER_S_BAR: f64 = 1e-3 / 1e5;

/// ISO 6358 mass flow (kg/s) from `p1_abs` to `p2_abs` (Pa absolute) through a sonic
/// conductance `c_m3_s_pa` (m3/(s Pa), ANR) with critical pressure ratio `b`, the upstream
/// air at [`AIR_TEMPERATURE_K`]. Zero when `p2 >= p1`.
pub fn iso6358_mass_flow(c_m3_s_pa: f64, b: f64, p1_abs: f64, p2_abs: f64) -> f64 {
    if p1_abs <= p2_abs || c_m3_s_pa <= 0.0 {
        return 0.0;
    }
    let choked = c_m3_s_pa * p1_abs * ANR_DENSITY_KG_M3;
    let subsonic = |r: f64| {
        let z = (r - b) / (1.0 - b);
        choked * (1.0 - z * z).max(0.0).sqrt()
    };
    let r = p2_abs / p1_abs;
    if r <= b {
        choked
    } else if r <= LAMINAR_RATIO {
        subsonic(r)
    } else {
        subsonic(LAMINAR_RATIO) * (1.0 - r) / (1.0 - LAMINAR_RATIO)
    }
}

/// A proportional valve as its datasheet gives it: one file of `models/valves/`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ValveSpec {
    /// The valve as its maker names it (`Festo MPYE-5-1/4-420-B`).
    pub name: String,
    /// Where each number comes from.
    pub source: String,
    /// ISO 6358 sonic conductance `C` of the supply path at full opening (l/(s bar), ANR).
    pub sonic_conductance_l_per_s_bar: f64,
    /// ISO 6358 critical pressure ratio `b` of the supply path.
    pub critical_pressure_ratio: f64,
    /// `C` of the exhaust path (l/(s bar)); default the supply path's.
    #[cfg_attr(feature = "serde", serde(default))]
    pub exhaust_sonic_conductance_l_per_s_bar: Option<f64>,
    /// `b` of the exhaust path; default the supply path's.
    #[cfg_attr(feature = "serde", serde(default))]
    pub exhaust_critical_pressure_ratio: Option<f64>,
    /// The spool's first-order time constant (s): `1 / (2 pi f)` of its limit frequency.
    pub spool_time_constant_s: f64,
    /// The pressure loop's proportional band (Pa): the spool is fully open at this much
    /// pressure error.
    pub pressure_band_pa: f64,
}

/// Largest sonic conductance a valve file may give (l/(s bar)): a Festo MPYE-5-3/8, the
/// largest proportional valve of the series, has about 9; 100 is a typo.
pub const CONDUCTANCE_MAX_L_PER_S_BAR: f64 = 100.0;

impl ValveSpec {
    /// Every field in range; errors name the field.
    pub fn validate(&self) -> Result<(), Invalid> {
        let conductance = |name: &'static str, v: f64| {
            check(
                v.is_finite() && v > 0.0 && v <= CONDUCTANCE_MAX_L_PER_S_BAR,
                name,
                v,
                "must be > 0 and at most 100 l/(s bar) (a Festo MPYE-5-3/8 has about 9)",
            )
        };
        let ratio = |name: &'static str, v: f64| {
            check(
                v.is_finite() && (0.0..1.0).contains(&v),
                name,
                v,
                "must be 0..1 (ISO 6358's critical pressure ratio; about 0.2-0.5 for valves)",
            )
        };
        conductance(
            "sonic_conductance_l_per_s_bar",
            self.sonic_conductance_l_per_s_bar,
        )?;
        ratio("critical_pressure_ratio", self.critical_pressure_ratio)?;
        if let Some(c) = self.exhaust_sonic_conductance_l_per_s_bar {
            conductance("exhaust_sonic_conductance_l_per_s_bar", c)?;
        }
        if let Some(b) = self.exhaust_critical_pressure_ratio {
            ratio("exhaust_critical_pressure_ratio", b)?;
        }
        within(
            "spool_time_constant_s",
            self.spool_time_constant_s,
            1e-4,
            0.1,
            "must be 0.1 ms to 100 ms (proportional valves have limit frequencies of 10-1000 Hz)",
        )?;
        within(
            "pressure_band_pa",
            self.pressure_band_pa,
            1e3,
            6e5,
            "must be 1e3 to 6e5 Pa (full opening at 0.01-6 bar of error)",
        )?;
        Ok(())
    }
}

/// The pneumatics between a valve and a muscle, as a scenario or plant file sets them
/// (`[plant.pneumatics]`).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PneumaticsSettings {
    /// A shipped valve (`models/valves/<name>.toml` of pma-model: `mpye-5-1-8-hf`,
    /// `mpye-5-1-4`, `mpye-5-3-8`), a valve file's path, or `ideal` for the `[plant.valve]`
    /// model (instantaneous, or its first-order lag).
    pub valve: String,
    /// Supply pressure (Pa gauge). The default 6 bar is the DMSP's rating: a valve stuck
    /// open cannot take the muscle past it.
    #[cfg_attr(feature = "serde", serde(default = "default_supply"))]
    pub supply_pressure_pa: f64,
    /// Tube from the valve to the muscle (m).
    #[cfg_attr(feature = "serde", serde(default = "default_tube_length"))]
    pub tube_length_m: f64,
    /// The tube's bore (m).
    #[cfg_attr(feature = "serde", serde(default = "default_tube_bore"))]
    pub tube_bore_m: f64,
    /// Fittings' and end caps' dead volume (m3).
    #[cfg_attr(feature = "serde", serde(default = "default_fittings"))]
    pub fitting_volume_m3: f64,
    /// Polytropic exponent of the air in the muscle: 1 isothermal .. 1.4 adiabatic.
    #[cfg_attr(feature = "serde", serde(default = "default_exponent"))]
    pub polytropic_exponent: f64,
}

fn default_supply() -> f64 {
    6.0e5
}
fn default_tube_length() -> f64 {
    1.0
}
fn default_tube_bore() -> f64 {
    0.006
}
fn default_fittings() -> f64 {
    5e-6
}
fn default_exponent() -> f64 {
    1.0
}

impl PneumaticsSettings {
    /// Whether this selects the `[plant.valve]` model instead of a flow-limited one.
    pub fn is_ideal(&self) -> bool {
        self.valve == "ideal"
    }

    /// Every field in range (the valve file is checked where it is loaded).
    pub fn validate(&self) -> Result<(), Invalid> {
        within(
            "supply_pressure_pa",
            self.supply_pressure_pa,
            1e5,
            1e6,
            "must be 1 to 10 bar gauge (a proportional valve's supply range)",
        )?;
        within(
            "tube_length_m",
            self.tube_length_m,
            0.01,
            20.0,
            "must be 0.01 to 20 m (a tube of 0 m is no tube: put the valve on the muscle with 0.01)",
        )?;
        within(
            "tube_bore_m",
            self.tube_bore_m,
            1e-3,
            0.02,
            "must be 1 to 20 mm (pneumatic tubing's inner diameters)",
        )?;
        within(
            "fitting_volume_m3",
            self.fitting_volume_m3,
            0.0,
            1e-3,
            "must be 0 to 1e-3 m3 (one litre of fittings is a tank)",
        )?;
        within(
            "polytropic_exponent",
            self.polytropic_exponent,
            1.0,
            1.4,
            "must be 1 to 1.4 (isothermal to adiabatic)",
        )?;
        Ok(())
    }

    /// The tube's volume (m3).
    pub fn tube_volume_m3(&self) -> f64 {
        std::f64::consts::PI * self.tube_bore_m.powi(2) / 4.0 * self.tube_length_m
    }

    /// The tube's transport delay (s).
    pub fn transport_delay_s(&self) -> f64 {
        self.tube_length_m / SPEED_OF_SOUND_M_S
    }

    /// The flow model of `spec` behind these pneumatics, into `chamber`.
    pub fn flow(&self, spec: &ValveSpec, chamber: Chamber) -> FlowParams {
        let c_in = spec.sonic_conductance_l_per_s_bar * L_PER_S_BAR;
        FlowParams {
            inlet_conductance_m3_s_pa: c_in,
            inlet_critical_ratio: spec.critical_pressure_ratio,
            exhaust_conductance_m3_s_pa: spec
                .exhaust_sonic_conductance_l_per_s_bar
                .map_or(c_in, |c| c * L_PER_S_BAR),
            exhaust_critical_ratio: spec
                .exhaust_critical_pressure_ratio
                .unwrap_or(spec.critical_pressure_ratio),
            spool_time_constant_s: spec.spool_time_constant_s,
            pressure_band_pa: spec.pressure_band_pa,
            supply_pa: self.supply_pressure_pa,
            dead_volume_m3: self.tube_volume_m3() + self.fitting_volume_m3,
            polytropic_exponent: self.polytropic_exponent,
            chamber,
        }
    }
}

impl Default for PneumaticsSettings {
    /// The `ideal` valve (the `[plant.valve]` model) with the default tube and supply.
    fn default() -> Self {
        Self {
            valve: "ideal".into(),
            supply_pressure_pa: default_supply(),
            tube_length_m: default_tube_length(),
            tube_bore_m: default_tube_bore(),
            fitting_volume_m3: default_fittings(),
            polytropic_exponent: default_exponent(),
        }
    }
}

/// A braided muscle's air space: its rest length, inner diameter and braid angle, and
/// the braid's geometry they give.
///
/// The geometry is worked out once, when the chamber is made: the volume is read at
/// every physics substep of every muscle, and its cosine and tangent of the braid angle
/// were a fifth of the valves' cost (issue 50). The fields are private so that the
/// geometry cannot fall out of step with them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chamber {
    rest_length_m: f64,
    diameter_m: f64,
    braid_angle_rad: f64,
    /// The braid's thread length `b` (m).
    thread_m: f64,
    /// `1 / (4 pi N^2)` of the braid's `N` turns.
    volume_factor: f64,
}

impl Chamber {
    /// A DMSP of inner diameter `diameter_m` and nominal length `rest_length_m`.
    pub fn dmsp(diameter_m: f64, rest_length_m: f64) -> Self {
        Self::braided(rest_length_m, diameter_m, DMSP_BRAID_ANGLE_RAD)
    }

    /// A braided muscle of rest length `rest_length_m`, inner diameter at rest
    /// `diameter_m` and braid angle at rest `braid_angle_rad`.
    pub fn braided(rest_length_m: f64, diameter_m: f64, braid_angle_rad: f64) -> Self {
        // The braid's thread length `b` and turns `N` (Chou & Hannaford).
        let thread_m = rest_length_m / braid_angle_rad.cos();
        let turns = rest_length_m * braid_angle_rad.tan() / (std::f64::consts::PI * diameter_m);
        Self {
            rest_length_m,
            diameter_m,
            braid_angle_rad,
            thread_m,
            volume_factor: 1.0 / (4.0 * std::f64::consts::PI * turns * turns),
        }
    }

    /// Nominal (rest) length (m).
    pub fn rest_length_m(&self) -> f64 {
        self.rest_length_m
    }

    /// Inner diameter at rest (m): 10 / 20 / 40 mm for DMSP-10 / 20 / 40.
    pub fn diameter_m(&self) -> f64 {
        self.diameter_m
    }

    /// Braid angle at rest (rad).
    pub fn braid_angle_rad(&self) -> f64 {
        self.braid_angle_rad
    }

    /// The air volume (m3) at contraction `x_m`, and its derivative in `x_m` (m2).
    pub fn volume(&self, x_m: f64) -> (f64, f64) {
        let (b, k) = (self.thread_m, self.volume_factor);
        // A stretched muscle (x < 0) keeps its rest volume's slope; a contraction beyond
        // the braid's lock keeps the volume there. Both lie outside any working stroke.
        let l_min = b / 3f64.sqrt();
        let l = (self.rest_length_m - x_m).clamp(l_min, b);
        let v = k * l * (b * b - l * l);
        // dV/dL = k (b^2 - 3 L^2); dV/dx = -dV/dL.
        let dv_dx = -k * (b * b - 3.0 * l * l);
        (v, dv_dx)
    }
}

/// The flow model's numbers, resolved (SI units): a valve, its supply, the dead volume
/// and the muscle's chamber.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowParams {
    /// Supply path's sonic conductance at full opening (m3/(s Pa)).
    pub inlet_conductance_m3_s_pa: f64,
    /// Supply path's critical pressure ratio.
    pub inlet_critical_ratio: f64,
    /// Exhaust path's sonic conductance (m3/(s Pa)).
    pub exhaust_conductance_m3_s_pa: f64,
    /// Exhaust path's critical pressure ratio.
    pub exhaust_critical_ratio: f64,
    /// Spool time constant (s).
    pub spool_time_constant_s: f64,
    /// Pressure error at full opening (Pa).
    pub pressure_band_pa: f64,
    /// Supply pressure (Pa gauge).
    pub supply_pa: f64,
    /// Tube and fittings (m3).
    pub dead_volume_m3: f64,
    /// Polytropic exponent.
    pub polytropic_exponent: f64,
    /// The muscle.
    pub chamber: Chamber,
}

/// The state of one muscle's pneumatics: its pressure and the spool's opening.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowState {
    /// Gauge pressure in the muscle (Pa).
    pub pressure_pa: f64,
    /// Spool opening, -1 (exhaust fully open) .. 1 (supply fully open).
    pub opening: f64,
}

impl FlowParams {
    /// The spool's opening the pressure loop asks for at `pressure_pa` against `set_pa`.
    fn demanded_opening(&self, set_pa: f64, pressure_pa: f64) -> f64 {
        ((set_pa - pressure_pa) / self.pressure_band_pa).clamp(-1.0, 1.0)
    }

    /// Net mass flow into the muscle (kg/s) at `opening` and gauge `pressure_pa`.
    pub fn mass_flow(&self, opening: f64, pressure_pa: f64) -> f64 {
        let p = pressure_pa + ATMOSPHERE_PA;
        if opening > 0.0 {
            opening
                * iso6358_mass_flow(
                    self.inlet_conductance_m3_s_pa,
                    self.inlet_critical_ratio,
                    self.supply_pa + ATMOSPHERE_PA,
                    p,
                )
        } else if opening < 0.0 {
            opening
                * iso6358_mass_flow(
                    self.exhaust_conductance_m3_s_pa,
                    self.exhaust_critical_ratio,
                    p,
                    ATMOSPHERE_PA,
                )
        } else {
            0.0
        }
    }

    /// The pressure's rate (Pa/s) at `state`, the muscle at contraction `x_m` moving at
    /// `v_m_s`.
    pub fn pressure_rate(&self, state: FlowState, x_m: f64, v_m_s: f64) -> f64 {
        self.pressure_rate_in(state, self.air_volume(x_m), v_m_s)
    }

    /// The air's volume (m3, the muscle's and the dead volume) at contraction `x_m`, and
    /// its derivative in `x_m` (m2).
    fn air_volume(&self, x_m: f64) -> (f64, f64) {
        let (v_muscle, dv_dx) = self.chamber.volume(x_m);
        (v_muscle + self.dead_volume_m3, dv_dx)
    }

    /// [`FlowParams::pressure_rate`] with the air's volume and its slope given.
    fn pressure_rate_in(&self, state: FlowState, (volume, dv_dx): (f64, f64), v_m_s: f64) -> f64 {
        let p_abs = state.pressure_pa + ATMOSPHERE_PA;
        let m_dot = self.mass_flow(state.opening, state.pressure_pa);
        self.polytropic_exponent / volume
            * (R_AIR_J_PER_KG_K * AIR_TEMPERATURE_K * m_dot - p_abs * dv_dx * v_m_s)
    }

    /// Advances `state` by `h_s` toward the set point `set_pa`, the muscle at `x_m`
    /// moving at `v_m_s`: the spool exactly (first order over each internal step), the
    /// pressure by explicit Euler over internal steps of at most [`PRESSURE_STEP_MAX_S`].
    /// The pressure stays within vacuum (-1 atm) and the supply.
    pub fn advance(&self, state: &mut FlowState, set_pa: f64, h_s: f64, x_m: f64, v_m_s: f64) {
        self.advance_within(state, set_pa, h_s, (x_m, v_m_s), PRESSURE_STEP_MAX_S);
    }

    /// [`FlowParams::advance`] with internal steps of at most `step_max_s` (the
    /// convergence tests refine it).
    pub fn advance_within(
        &self,
        state: &mut FlowState,
        set_pa: f64,
        h_s: f64,
        motion: (f64, f64),
        step_max_s: f64,
    ) {
        let mut spool = FirstOrderFactor::default();
        self.advance_remembering(state, set_pa, h_s, motion, step_max_s, &mut spool);
    }

    /// [`FlowParams::advance_within`] with the spool's factor kept in `spool` between
    /// calls: a valve advanced substep by substep asks for the same one each time.
    pub(crate) fn advance_remembering(
        &self,
        state: &mut FlowState,
        set_pa: f64,
        h_s: f64,
        (x_m, v_m_s): (f64, f64),
        step_max_s: f64,
        spool: &mut FirstOrderFactor,
    ) {
        if h_s <= 0.0 {
            return;
        }
        let n = (h_s / step_max_s).ceil().max(1.0);
        let dt = h_s / n;
        let spool = spool.at(dt, self.spool_time_constant_s);
        // The muscle's length is held over the step: its volume once, not at every
        // internal step.
        let air = self.air_volume(x_m);
        for _ in 0..n as u32 {
            let want = self.demanded_opening(set_pa, state.pressure_pa);
            state.opening += spool * (want - state.opening);
            let rate = self.pressure_rate_in(*state, air, v_m_s);
            state.pressure_pa =
                (state.pressure_pa + dt * rate).clamp(-ATMOSPHERE_PA, self.supply_pa);
        }
    }
}

/// A first-order factor `1 - exp(-dt / tau)` over a step `dt`, recomputed only when `dt`
/// or `tau` changes (the same value bit for bit): the lag valve's over its substep, the
/// flow valve's spool over its internal step, where the exponential was a fourteenth of
/// the valve's cost (issue 50).
///
/// Two steps are kept. A valve's dead time splits one substep a period into two pieces of
/// odd lengths, each seen once; the substep's own step, kept in the first slot, then still
/// matches when the pieces are over (with one slot, three exponentials a period and valve).
/// A step matched in the second slot moves to the first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FirstOrderFactor {
    slots: [FactorAt; 2],
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FactorAt {
    dt_s: f64,
    tau_s: f64,
    factor: f64,
}

impl FactorAt {
    fn matches(&self, dt_s: f64, tau_s: f64) -> bool {
        dt_s.to_bits() == self.dt_s.to_bits() && tau_s.to_bits() == self.tau_s.to_bits()
    }
}

impl Default for FirstOrderFactor {
    fn default() -> Self {
        // NaN matches no step: the first calls compute.
        let empty = FactorAt {
            dt_s: f64::NAN,
            tau_s: f64::NAN,
            factor: 0.0,
        };
        Self { slots: [empty; 2] }
    }
}

impl FirstOrderFactor {
    pub(crate) fn at(&mut self, dt_s: f64, tau_s: f64) -> f64 {
        if self.slots[0].matches(dt_s, tau_s) {
            return self.slots[0].factor;
        }
        if self.slots[1].matches(dt_s, tau_s) {
            self.slots.swap(0, 1);
            return self.slots[0].factor;
        }
        let computed = FactorAt {
            dt_s,
            tau_s,
            factor: 1.0 - (-dt_s / tau_s).exp(),
        };
        // The first step ever seen takes the first slot; later new steps the second.
        let slot = usize::from(!self.slots[0].dt_s.is_nan());
        self.slots[slot] = computed;
        computed.factor
    }
}

/// A pressure step's figures: rise (10-90 %) and fall (90-10 %) times and the peak rates.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct StepResponse {
    /// From `low` to `high`: 10 % to 90 % of the step (s).
    pub rise_10_90_s: f64,
    /// From `high` to `low`: 90 % to 10 % of the step (s).
    pub fall_90_10_s: f64,
    /// Time to 63 % of the rise (s), from the set point's change.
    pub rise_63_s: f64,
    /// Fastest pressure rise (Pa/s).
    pub peak_rise_rate_pa_s: f64,
    /// Fastest pressure fall (Pa/s, positive).
    pub peak_fall_rate_pa_s: f64,
    /// The pressure reached at the end of the rise (Pa).
    pub reached_pa: f64,
}

/// The step `low -> high -> low` (Pa gauge) of a muscle held at contraction `x_m`, each
/// half `hold_s` long, integrated at `h_s`; the transport delay of `delay_s` is added to
/// both edges.
pub fn step_response(
    flow: &FlowParams,
    low_pa: f64,
    high_pa: f64,
    x_m: f64,
    hold_s: f64,
    h_s: f64,
    delay_s: f64,
) -> StepResponse {
    let mut state = FlowState {
        pressure_pa: low_pa,
        opening: 0.0,
    };
    let steps = (hold_s / h_s).round() as usize;
    let span = high_pa - low_pa;
    let trace = |set: f64, state: &mut FlowState| {
        let mut out = Vec::with_capacity(steps + 1);
        out.push(state.pressure_pa);
        for _ in 0..steps {
            flow.advance(state, set, h_s, x_m, 0.0);
            out.push(state.pressure_pa);
        }
        out
    };
    let up = trace(high_pa, &mut state);
    let reached = state.pressure_pa;
    let down = trace(low_pa, &mut state);
    // The crossing time, interpolated linearly between the samples around it.
    let crossing = |v: &[f64], level: f64, rising: bool| {
        let past = |p: f64| if rising { p >= level } else { p <= level };
        match v.iter().position(|&p| past(p)) {
            None => f64::NAN,
            Some(0) => delay_s,
            Some(i) => {
                let (a, b) = (v[i - 1], v[i]);
                let frac = if b != a { (level - a) / (b - a) } else { 1.0 };
                (i as f64 - 1.0 + frac) * h_s + delay_s
            }
        }
    };
    let level = |f: f64| low_pa + f * span;
    let peak = |v: &[f64]| {
        v.windows(2)
            .map(|w| (w[1] - w[0]) / h_s)
            .fold(0.0f64, |m, r| m.max(r.abs()))
    };
    StepResponse {
        rise_10_90_s: crossing(&up, level(0.9), true) - crossing(&up, level(0.1), true),
        fall_90_10_s: crossing(&down, level(0.1), false) - crossing(&down, level(0.9), false),
        rise_63_s: crossing(&up, level(0.632), true),
        peak_rise_rate_pa_s: peak(&up),
        peak_fall_rate_pa_s: peak(&down),
        reached_pa: reached,
    }
}

/// The shipped valve files: `(name, file text)`.
pub const SHIPPED_VALVES: [(&str, &str); 3] = [
    (
        "mpye-5-1-8-hf",
        include_str!("../models/valves/mpye-5-1-8-hf.toml"),
    ),
    (
        "mpye-5-1-4",
        include_str!("../models/valves/mpye-5-1-4.toml"),
    ),
    (
        "mpye-5-3-8",
        include_str!("../models/valves/mpye-5-3-8.toml"),
    ),
];

/// A valve file that could not be read, parsed or validated: one line naming the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("valve file `{file}`: {message}")]
pub struct ValveFileError {
    /// The file (or the shipped name).
    pub file: String,
    /// What is wrong, naming the field.
    pub message: String,
}

#[cfg(feature = "serde")]
impl ValveSpec {
    /// Parses and validates a valve file's text; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, ValveFileError> {
        let err = |message: String| ValveFileError {
            file: file.to_owned(),
            message,
        };
        let spec: ValveSpec =
            toml::from_str(text).map_err(|e| err(e.message().trim().to_owned()))?;
        spec.validate().map_err(|e| err(e.to_string()))?;
        Ok(spec)
    }

    /// A shipped valve by name (`mpye-5-1-4`), or a valve file by path (`.toml`).
    pub fn load(name_or_path: &str) -> Result<Self, ValveFileError> {
        if let Some((name, text)) = SHIPPED_VALVES.iter().find(|(n, _)| *n == name_or_path) {
            return Self::from_toml_str(
                text,
                &format!("crates/pma-model/models/valves/{name}.toml"),
            );
        }
        if !name_or_path.ends_with(".toml") {
            let names: Vec<&str> = SHIPPED_VALVES.iter().map(|(n, _)| *n).collect();
            return Err(ValveFileError {
                file: name_or_path.to_owned(),
                message: format!(
                    "no such valve: `ideal`, {} or a valve file's path (.toml)",
                    names.join(", ")
                ),
            });
        }
        let text = std::fs::read_to_string(name_or_path).map_err(|e| ValveFileError {
            file: name_or_path.to_owned(),
            message: e.to_string(),
        })?;
        Self::from_toml_str(&text, name_or_path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mpye_1_4() -> ValveSpec {
        ValveSpec {
            name: "test".into(),
            source: String::new(),
            sonic_conductance_l_per_s_bar: 6.25,
            critical_pressure_ratio: 0.23,
            exhaust_sonic_conductance_l_per_s_bar: None,
            exhaust_critical_pressure_ratio: None,
            spool_time_constant_s: 0.002,
            pressure_band_pa: 3e4,
        }
    }

    #[test]
    fn the_flow_is_choked_below_b_continuous_at_b_and_zero_at_equal_pressures() {
        let c = 6.25 * L_PER_S_BAR;
        let choked = iso6358_mass_flow(c, 0.23, 7e5, 1e5);
        // C p1 rho0: 6.25e-8 * 7e5 * 1.185 = 0.0518 kg/s.
        assert!((choked - 6.25e-8 * 7e5 * 1.185).abs() < 1e-12, "{choked}");
        let at_b = iso6358_mass_flow(c, 0.23, 7e5, 0.23 * 7e5);
        let above_b = iso6358_mass_flow(c, 0.23, 7e5, 0.23 * 7e5 + 1.0);
        assert!((at_b - above_b).abs() < 1e-6 * choked);
        assert_eq!(iso6358_mass_flow(c, 0.23, 7e5, 7e5), 0.0);
        assert_eq!(iso6358_mass_flow(c, 0.23, 7e5, 8e5), 0.0);
        // The laminar blend meets the subsonic law at its edge.
        let r = LAMINAR_RATIO;
        let left = iso6358_mass_flow(c, 0.23, 7e5, r * 7e5 - 1e-3);
        let right = iso6358_mass_flow(c, 0.23, 7e5, r * 7e5 + 1e-3);
        assert!((left - right).abs() < 1e-6 * choked, "{left} {right}");
    }

    #[test]
    fn the_rest_volume_is_the_cylinder_and_contraction_swells_it() {
        let c = Chamber::dmsp(0.020, 1.0);
        let (v0, _) = c.volume(0.0);
        let cylinder = std::f64::consts::PI * 0.02f64.powi(2) / 4.0;
        assert!((v0 - cylinder).abs() < 1e-12, "{v0} {cylinder}");
        let (v10, _) = c.volume(0.10);
        let (v25, _) = c.volume(0.25);
        // 0.31 / 0.46 / 0.58 l per metre at 0 / 10 / 25 %.
        assert!((v10 * 1e3 - 0.4636).abs() < 0.0005, "{v10}");
        assert!((v25 * 1e3 - 0.5824).abs() < 0.0005, "{v25}");
        // The slope against a finite difference.
        let (_, dv) = c.volume(0.1);
        let fd = (c.volume(0.1 + 1e-7).0 - c.volume(0.1 - 1e-7).0) / 2e-7;
        assert!((dv - fd).abs() < 1e-6 * fd.abs(), "{dv} {fd}");
    }

    #[test]
    fn choked_filling_of_a_fixed_volume_matches_the_closed_form() {
        // Isothermal, volume fixed, spool fully open (a huge band error), pressure far below
        // b of the supply: dp/dt = R T C p1 rho0 / V, a constant.
        let s = PneumaticsSettings {
            valve: "x".into(),
            fitting_volume_m3: 0.0,
            ..PneumaticsSettings::default()
        };
        let spec = mpye_1_4();
        let flow = s.flow(&spec, Chamber::dmsp(0.02, 1.0));
        let state = FlowState {
            pressure_pa: 0.0,
            opening: 1.0,
        };
        let v = flow.chamber.volume(0.0).0 + s.tube_volume_m3();
        let expected = R_AIR_J_PER_KG_K * AIR_TEMPERATURE_K * 6.25e-8 * (7e5 + 1325.0) * 1.185 / v;
        let rate = flow.pressure_rate(state, 0.0, 0.0);
        assert!(
            (rate - expected).abs() < 1e-9 * expected,
            "{rate} {expected}"
        );
        // Contracting at constant mass lowers the pressure: p V = const.
        let shut = FlowState {
            pressure_pa: 3e5,
            opening: 0.0,
        };
        let (v0, dv) = flow.chamber.volume(0.05);
        let total = v0 + s.tube_volume_m3();
        let r = flow.pressure_rate(shut, 0.05, 0.1);
        assert!(
            (r + (3e5 + ATMOSPHERE_PA) * dv * 0.1 / total).abs() < 1e-6,
            "{r}"
        );
    }

    #[test]
    fn a_step_settles_at_its_set_point_and_converges_in_the_step() {
        let s = PneumaticsSettings {
            valve: "x".into(),
            supply_pressure_pa: 7e5,
            ..PneumaticsSettings::default()
        };
        let flow = s.flow(&mpye_1_4(), Chamber::dmsp(0.02, 1.2));
        let coarse = step_response(&flow, 0.0, 6e5, 0.0, 0.5, 1e-3, 0.0);
        let fine = step_response(&flow, 0.0, 6e5, 0.0, 0.5, 2.5e-4, 0.0);
        assert!((coarse.reached_pa - 6e5).abs() < 2e3, "{coarse:?}");
        assert!(
            coarse.rise_10_90_s > 0.0 && coarse.fall_90_10_s > 0.0,
            "{coarse:?}"
        );
        // Quartering the outer step moves the times by less than one coarse step.
        assert!(
            (coarse.rise_10_90_s - fine.rise_10_90_s).abs() <= 1e-3,
            "{coarse:?} {fine:?}"
        );
        assert!(
            (coarse.fall_90_10_s - fine.fall_90_10_s).abs() <= 1e-3,
            "{coarse:?} {fine:?}"
        );
    }

    /// Issue 50: a valve keeps its spool factor between substeps and a chamber its
    /// braid's geometry, worked out once. Both must give, bit for bit, what the formulas
    /// worked out afresh at every call give: the trajectories of every figure rest on it.
    #[test]
    fn regression_the_remembered_spool_factor_and_braid_change_no_bit() {
        let (length, diameter) = (0.4, 0.02);
        let chamber = Chamber::dmsp(diameter, length);
        // The volume as it was computed at every call before (Chou & Hannaford).
        let volume_afresh = |x: f64| {
            let b = length / DMSP_BRAID_ANGLE_RAD.cos();
            let turns = length * DMSP_BRAID_ANGLE_RAD.tan() / (std::f64::consts::PI * diameter);
            let k = 1.0 / (4.0 * std::f64::consts::PI * turns * turns);
            let l = (length - x).clamp(b / 3f64.sqrt(), b);
            (k * l * (b * b - l * l), -k * (b * b - 3.0 * l * l))
        };
        for x in [-0.01, 0.0, 0.013, 0.05, 0.3] {
            assert_eq!(chamber.volume(x), volume_afresh(x), "x = {x}");
        }
        // A valve's substeps, some split by a command's arrival (shorter pieces): the
        // remembered factor against a fresh one at each call.
        let flow = PneumaticsSettings::default().flow(&mpye_1_4(), chamber);
        let start = FlowState {
            pressure_pa: 1e5,
            opening: 0.0,
        };
        let (mut kept, mut fresh) = (start, start);
        let mut spool = FirstOrderFactor::default();
        for k in 0..400 {
            let set_pa = if (k / 40) % 2 == 0 { 4.5e5 } else { 0.5e5 };
            let h = if k % 7 == 3 { 1.3e-4 } else { 2.5e-4 };
            let motion = (0.03, -0.02);
            flow.advance_remembering(
                &mut kept,
                set_pa,
                h,
                motion,
                PRESSURE_STEP_MAX_S,
                &mut spool,
            );
            flow.advance(&mut fresh, set_pa, h, motion.0, motion.1);
            assert_eq!(kept, fresh, "substep {k}");
        }
        assert!(kept.pressure_pa > 0.4e5, "{kept:?}");
    }

    #[test]
    fn regression_a_two_step_factor_cache_gives_each_steps_own_factor() {
        // Substeps, the pieces a command's arrival cuts (each of its own length), a new
        // time constant and a new substep: every call's factor is its own step's.
        let mut cache = FirstOrderFactor::default();
        let mut calls = Vec::new();
        for k in 0..200u32 {
            let tau = if k < 120 { 5e-3 } else { 7e-3 };
            let h = if k < 160 { 2.5e-4 } else { 1.25e-4 };
            if k % 4 == 1 {
                let cut = h * (0.1 + 0.8 * f64::from(k % 13) / 13.0);
                calls.extend([(cut, tau), (h - cut, tau)]);
            } else {
                calls.push((h, tau));
            }
        }
        for (i, &(dt, tau)) in calls.iter().enumerate() {
            let want = 1.0 - (-dt / tau).exp();
            assert_eq!(cache.at(dt, tau).to_bits(), want.to_bits(), "call {i}");
        }
    }

    /// The rise and fall of the trainer's muscle behind the shipped valve move by less
    /// than 2 % when the pressure's own integration step is quartered (50 -> 12.5 us).
    #[test]
    fn the_pressure_integration_is_converged_at_its_step() {
        let s = PneumaticsSettings {
            valve: "x".into(),
            ..PneumaticsSettings::default()
        };
        let flow = s.flow(&mpye_1_4(), Chamber::dmsp(0.02, 1.2));
        let times = |step_max: f64| {
            let mut st = FlowState {
                pressure_pa: 0.0,
                opening: 0.0,
            };
            let h = 1e-4;
            let (mut t10, mut t90, mut t) = (f64::NAN, f64::NAN, 0.0);
            while t < 0.5 {
                flow.advance_within(&mut st, 5e5, h, (0.0, 0.0), step_max);
                t += h;
                if t10.is_nan() && st.pressure_pa >= 0.5e5 {
                    t10 = t;
                }
                if t90.is_nan() && st.pressure_pa >= 4.5e5 {
                    t90 = t;
                }
            }
            t90 - t10
        };
        let (coarse, fine) = (times(PRESSURE_STEP_MAX_S), times(PRESSURE_STEP_MAX_S / 4.0));
        assert!((coarse - fine).abs() <= 0.02 * fine, "{coarse} {fine}");
    }

    #[test]
    fn bad_valve_files_name_their_field() {
        let mut v = mpye_1_4();
        v.sonic_conductance_l_per_s_bar = -1.0;
        assert!(v
            .validate()
            .unwrap_err()
            .to_string()
            .contains("sonic_conductance"));
        let mut v = mpye_1_4();
        v.critical_pressure_ratio = 1.2;
        assert!(v
            .validate()
            .unwrap_err()
            .to_string()
            .contains("critical_pressure_ratio"));
        let s = PneumaticsSettings {
            tube_length_m: 0.0,
            ..PneumaticsSettings::default()
        };
        assert!(s
            .validate()
            .unwrap_err()
            .to_string()
            .contains("tube_length_m"));
    }
}
