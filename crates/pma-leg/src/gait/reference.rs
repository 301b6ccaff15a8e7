//! Normative gait references for the exoskeleton's legs: hip and knee flexion (and, for an
//! adult's, ankle dorsiflexion) as Fourier series fitted to normative data
//! (`crates/pma-leg/models/gait/`), time-scaled to a stride period, started smoothly from
//! standing, with analytic first and second derivatives. Flexion is positive.
//!
//! Two data sets: typically developing children at five speed classes (Schwartz,
//! Rozumalski & Trost 2008, via `tools/fit_gait.py`; the in-air scenarios' reference), and
//! adults on a treadmill at measured speeds (Fukuchi, Fukuchi & Duarte 2018, CC BY 4.0, via
//! `tools/fit_adult_gait.py`; the treadmill's), the latter with the mean joint moments and
//! ground reaction forces to compare a run with ([`AdultNorms`]).

use crate::base::{invalid, LegError};
use pma_model::error::{non_negative, positive};
use serde::Deserialize;
use std::f64::consts::TAU;
use std::fmt;
use std::str::FromStr;

const FOURIER_FILE: &str = "crates/pma-leg/models/gait/schwartz2008_fourier.toml";
const FOURIER_TOML: &str = include_str!("../../models/gait/schwartz2008_fourier.toml");
const ADULT_FILE: &str = "crates/pma-leg/models/gait/fukuchi2018.toml";
const ADULT_TOML: &str = include_str!("../../models/gait/fukuchi2018.toml");

/// Where a gait reference comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GaitData {
    /// Typically developing children, speed classes `very-slow` .. `very-fast` (Schwartz
    /// et al. 2008): the in-air scenarios' reference.
    #[default]
    Schwartz2008,
    /// Adults on a treadmill at their measured mean speeds (Fukuchi et al. 2018), with
    /// the ankle's curve and the mean moments and ground reactions.
    Fukuchi2018,
}

impl GaitData {
    /// The name a scenario gives it.
    pub fn as_str(self) -> &'static str {
        match self {
            GaitData::Schwartz2008 => "schwartz2008",
            GaitData::Fukuchi2018 => "fukuchi2018",
        }
    }
}

/// Samples of the adult data's mean curves over one cycle (0, 1, ..., 100 %).
pub const CURVE_SAMPLES: usize = 101;

/// An adult condition's mean curves (101 samples from initial contact; moments internal,
/// extensor and plantarflexor positive, N m/kg; ground reaction in body weights).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormCurves {
    /// Hip flexion (deg).
    pub hip_deg: Vec<f64>,
    /// Knee flexion (deg).
    pub knee_deg: Vec<f64>,
    /// Ankle dorsiflexion (deg).
    pub ankle_deg: Vec<f64>,
    /// Hip moment (N m/kg, extensor positive).
    pub hip_moment_nm_kg: Vec<f64>,
    /// Knee moment (N m/kg, extensor positive).
    pub knee_moment_nm_kg: Vec<f64>,
    /// Ankle moment (N m/kg, plantarflexor positive).
    pub ankle_moment_nm_kg: Vec<f64>,
    /// Vertical ground reaction (body weights).
    pub grf_vertical_bw: Vec<f64>,
    /// Fore-aft ground reaction (body weights, forward positive).
    pub grf_fore_aft_bw: Vec<f64>,
}

/// One adult condition of the data: its speed, toe-off, angle series and mean curves.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdultNorms {
    /// The subjects' mean treadmill speed (m/s).
    pub speed_m_s: f64,
    /// Subjects averaged.
    pub subjects: usize,
    /// Mean toe-off phase (0-1).
    pub toe_off: f64,
    /// Hip flexion.
    pub hip: FourierSeries,
    /// Knee flexion.
    pub knee: FourierSeries,
    /// Ankle dorsiflexion.
    pub ankle: FourierSeries,
    /// Mean curves.
    pub curves: NormCurves,
    /// Their standard deviations over subjects.
    pub sd: NormCurves,
}

impl AdultNorms {
    /// The condition of the adult data at `speed_m_s` (within 5 mm/s of its mean speed);
    /// the error names the field and lists the speeds there are.
    pub fn at(speed_m_s: f64) -> Result<Self, LegError> {
        let all = Self::all()?;
        let speeds: Vec<String> = all.iter().map(|c| format!("{:.2}", c.speed_m_s)).collect();
        all.into_iter()
            .find(|c| (c.speed_m_s - speed_m_s).abs() < 0.005)
            .ok_or_else(|| {
                pma_model::Invalid::new(
                    "gait.speed_m_per_s",
                    speed_m_s,
                    format!(
                        "is not a speed of the adult data (Fukuchi et al. 2018 walked at {} m/s)",
                        speeds.join(", ")
                    ),
                )
                .into()
            })
    }

    /// The mean hip and knee moments turned into the torques the joints need, flexion
    /// positive (minus the extensor moments), N m/kg over the cycle.
    pub fn flexion_torques_nm_kg(&self) -> [Vec<f64>; 2] {
        [
            &self.curves.hip_moment_nm_kg,
            &self.curves.knee_moment_nm_kg,
        ]
        .map(|m| m.iter().map(|v| -v).collect())
    }

    /// The mean vertical ground reaction's loading response over a stride of `stride_s`:
    /// the curve linearly interpolated to samples `dt_s` apart from heel strike to the mean
    /// toe-off, measured as the trainer's feet are ([`crate::gait::loading`]; body
    /// weights, body weights per second). A mean over subjects whose timing differs: each
    /// subject's own peak is higher and steeper than the mean curve's.
    pub fn grf_loading(&self, stride_s: f64, dt_s: f64) -> crate::gait::Loading {
        let curve = &self.curves.grf_vertical_bw;
        let stance_s = self.toe_off * stride_s;
        let samples: Vec<f64> = (0..)
            .map(|i| i as f64 * dt_s)
            .take_while(|t| *t <= stance_s)
            .map(|t_s| sample_cycle(curve, t_s / stride_s))
            .collect();
        crate::gait::loading(&samples, dt_s, stance_s)
    }

    /// Every condition of the adult data, slowest first.
    pub fn all() -> Result<Vec<Self>, LegError> {
        let file: std::collections::BTreeMap<String, toml::Value> = toml::from_str(ADULT_TOML)
            .map_err(|e| LegError::Parse {
                file: ADULT_FILE.into(),
                message: e.to_string(),
            })?;
        let mut out = Vec::new();
        for (name, v) in file {
            if name == "harmonics" {
                if v.as_integer() != Some(HARMONICS as i64) {
                    return Err(LegError::Parse {
                        file: ADULT_FILE.into(),
                        message: format!("{v} harmonics, expected {HARMONICS}"),
                    });
                }
                continue;
            }
            let c: AdultNorms = v.try_into().map_err(|e: toml::de::Error| LegError::Parse {
                file: ADULT_FILE.into(),
                message: format!("[{name}]: {e}"),
            })?;
            out.push(c);
        }
        out.sort_by(|a, b| a.speed_m_s.total_cmp(&b.speed_m_s));
        Ok(out)
    }
}

/// Number of harmonics shipped.
pub const HARMONICS: usize = 6;

/// Walking speed class of the normative data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GaitSpeed {
    /// Very slow.
    VerySlow,
    /// Slow (the default for training gait).
    #[default]
    Slow,
    /// Self-selected.
    Free,
    /// Fast.
    Fast,
    /// Very fast.
    VeryFast,
}

impl GaitSpeed {
    /// All classes, slowest first.
    pub const ALL: [GaitSpeed; 5] = [
        GaitSpeed::VerySlow,
        GaitSpeed::Slow,
        GaitSpeed::Free,
        GaitSpeed::Fast,
        GaitSpeed::VeryFast,
    ];

    /// Name as in configuration files.
    pub fn as_str(self) -> &'static str {
        match self {
            GaitSpeed::VerySlow => "very-slow",
            GaitSpeed::Slow => "slow",
            GaitSpeed::Free => "free",
            GaitSpeed::Fast => "fast",
            GaitSpeed::VeryFast => "very-fast",
        }
    }
}

impl fmt::Display for GaitSpeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for GaitSpeed {
    type Err = LegError;
    fn from_str(s: &str) -> Result<Self, LegError> {
        GaitSpeed::ALL
            .into_iter()
            .find(|g| g.as_str() == s)
            .ok_or_else(|| LegError::Parse {
                file: "gait speed".into(),
                message: format!(
                    "unknown speed `{s}` (expected very-slow, slow, free, fast or very-fast)"
                ),
            })
    }
}

/// A periodic angle (deg) as a Fourier series in the cycle phase.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FourierSeries {
    /// `a0, a1..a6` (deg).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub cos_deg: [f64; HARMONICS + 1],
    /// `0, b1..b6` (deg).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub sin_deg: [f64; HARMONICS + 1],
}

impl FourierSeries {
    /// The series of `samples_deg`, taken at phases `k / n` (k = 0..n) over one cycle:
    /// the discrete projection onto the harmonics, which on a uniform grid is the least
    /// squares fit (the harmonics are orthogonal there). `None` for fewer than
    /// `2 HARMONICS + 1` samples.
    pub fn project(samples_deg: &[f64]) -> Option<Self> {
        let n = samples_deg.len();
        if n < 2 * HARMONICS + 1 {
            return None;
        }
        let mut cos_deg = [0.0; HARMONICS + 1];
        let mut sin_deg = [0.0; HARMONICS + 1];
        for (k, y) in samples_deg.iter().enumerate() {
            cos_deg[0] += y;
            for (i, (s, c)) in Self::harmonics(k as f64 / n as f64).iter().enumerate() {
                cos_deg[i + 1] += y * c;
                sin_deg[i + 1] += y * s;
            }
        }
        cos_deg[0] /= n as f64;
        for i in 1..=HARMONICS {
            cos_deg[i] *= 2.0 / n as f64;
            sin_deg[i] *= 2.0 / n as f64;
        }
        Some(Self { cos_deg, sin_deg })
    }

    /// The angle at `phase` (deg).
    pub fn value_deg(&self, phase: f64) -> f64 {
        self.eval(&Self::harmonics(phase)).0
    }

    /// The sum of two series (their angles add at every phase).
    pub fn plus(&self, other: &Self) -> Self {
        Self {
            cos_deg: std::array::from_fn(|i| self.cos_deg[i] + other.cos_deg[i]),
            sin_deg: std::array::from_fn(|i| self.sin_deg[i] + other.sin_deg[i]),
        }
    }

    /// Largest |coefficient| (deg; NaN if any is NaN).
    pub fn largest_coefficient_deg(&self) -> f64 {
        self.cos_deg
            .iter()
            .chain(&self.sin_deg)
            .fold(0.0f64, |m, c| {
                if m.is_nan() || c.is_nan() {
                    f64::NAN
                } else {
                    m.max(c.abs())
                }
            })
    }

    /// `sin` and `cos` of each harmonic's angle at `phase`, shared by the joints.
    fn harmonics(phase: f64) -> [(f64, f64); HARMONICS] {
        std::array::from_fn(|i| (TAU * (i + 1) as f64 * phase).sin_cos())
    }

    /// Angle, rate and acceleration in degrees per unit phase (and its derivatives), from
    /// the harmonics of [`Self::harmonics`].
    fn eval(&self, harmonics: &[(f64, f64); HARMONICS]) -> (f64, f64, f64) {
        let (mut y, mut dy, mut ddy) = (self.cos_deg[0], 0.0, 0.0);
        for (k, &(s, c)) in (1..=HARMONICS).zip(harmonics) {
            let w = TAU * k as f64;
            let (a, b) = (self.cos_deg[k], self.sin_deg[k]);
            y += a * c + b * s;
            dy += w * (-a * s + b * c);
            ddy -= w * w * (a * c + b * s);
        }
        (y, dy, ddy)
    }

    /// The angle alone (deg), as [`Self::eval`] sums it, bit for bit.
    fn value(&self, harmonics: &[(f64, f64); HARMONICS]) -> f64 {
        let mut y = self.cos_deg[0];
        for (k, &(s, c)) in (1..=HARMONICS).zip(harmonics) {
            y += self.cos_deg[k] * c + self.sin_deg[k] * s;
        }
        y
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointCurves {
    /// Phase of toe-off (0-1): stance is `0..toe_off`.
    toe_off: f64,
    hip: FourierSeries,
    knee: FourierSeries,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FourierFile {
    harmonics: usize,
    veryslow: JointCurves,
    slow: JointCurves,
    free: JointCurves,
    fast: JointCurves,
    veryfast: JointCurves,
}

/// `curve` (samples at 0, 1/(n-1), ..., 1 of a cycle) at `phase`, linearly interpolated.
pub fn sample_cycle(curve: &[f64], phase: f64) -> f64 {
    let last = curve.len().saturating_sub(1);
    if last == 0 {
        return curve.first().copied().unwrap_or(0.0);
    }
    let x = phase.rem_euclid(1.0) * last as f64;
    let i = (x.floor() as usize).min(last - 1);
    let f = x - i as f64;
    curve[i] + f * (curve[i + 1] - curve[i])
}

/// How a reference leaves standing over its start-up ramp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StartUp {
    /// The legs stand straight (all angles 0) and the cycle's motion grows from nothing
    /// with a quintic over the ramp, at the gait's cadence from the first instant.
    #[default]
    Standing,
    /// The legs start in the gait's own posture in double support and the cadence grows
    /// from 0 with the same quintic as the belt's speed, so that a stance foot moves with
    /// the belt from the start. Needs a ramp of whole strides (the start is then double
    /// support: phase 0 for one leg and 0.5 for the other).
    InStep,
}

/// How the cycles run in time: at the stride period, or at a cadence growing with an
/// in-step start (cycles per second and its rate).
#[derive(Debug, Clone, Copy)]
enum Cadence {
    Steady { period: f64 },
    Growing { per_s: f64, per_s2: f64 },
}

/// A joint angle with its analytic derivatives.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointSample {
    /// Angle (rad), flexion positive.
    pub angle_rad: f64,
    /// Angular velocity (rad/s).
    pub velocity_rad_s: f64,
    /// Angular acceleration (rad/s^2).
    pub acceleration_rad_s2: f64,
}

/// Hip and knee references at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GaitSample {
    /// Hip flexion.
    pub hip: JointSample,
    /// Knee flexion.
    pub knee: JointSample,
    /// Ankle dorsiflexion, where the reference has it (zero otherwise): the passive
    /// ankle is not driven, its reference is only compared with.
    pub ankle: JointSample,
}

impl GaitSample {
    /// Hip, knee and ankle angles (rad).
    pub fn angles_rad(&self) -> [f64; 3] {
        [
            self.hip.angle_rad,
            self.knee.angle_rad,
            self.ankle.angle_rad,
        ]
    }
}

/// Hip and knee flexion over time: the normative cycle of a speed class, stretched to
/// `stride_period_s`, started over `ramp_s` by its [`StartUp`]: by default multiplied by a
/// quintic ramp `s(t)` from standing (all angles 0), so that angle, velocity and
/// acceleration all start at zero; or from the gait's own posture with its cadence grown
/// by the quintic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaitReference {
    hip: FourierSeries,
    knee: FourierSeries,
    /// The ankle's curve, where the data has one.
    ankle: Option<FourierSeries>,
    /// The adult condition's mean speed (m/s), for an adult reference.
    data_speed_m_s: Option<f64>,
    toe_off: f64,
    stride_period_s: f64,
    ramp_s: f64,
    start_up: StartUp,
    /// Where in the cycle this leg is at `t = 0` (0, or 0.5 for the other leg).
    phase_offset: f64,
}

/// Default stride period of a slow training gait (s).
pub const DEFAULT_STRIDE_PERIOD_S: f64 = 1.6;

impl GaitReference {
    /// The normative curves of `speed`, with a stride period and a start-up ramp (both s).
    pub fn normative(
        speed: GaitSpeed,
        stride_period_s: f64,
        ramp_s: f64,
    ) -> Result<Self, LegError> {
        positive("stride_period_s", stride_period_s)?;
        non_negative("ramp_s", ramp_s)?;
        let file: FourierFile = toml::from_str(FOURIER_TOML).map_err(|e| LegError::Parse {
            file: FOURIER_FILE.into(),
            message: e.to_string(),
        })?;
        if file.harmonics != HARMONICS {
            return Err(LegError::Parse {
                file: FOURIER_FILE.into(),
                message: format!("{} harmonics, expected {HARMONICS}", file.harmonics),
            });
        }
        let curves = match speed {
            GaitSpeed::VerySlow => file.veryslow,
            GaitSpeed::Slow => file.slow,
            GaitSpeed::Free => file.free,
            GaitSpeed::Fast => file.fast,
            GaitSpeed::VeryFast => file.veryfast,
        };
        Ok(Self {
            hip: curves.hip,
            knee: curves.knee,
            ankle: None,
            data_speed_m_s: None,
            toe_off: curves.toe_off,
            stride_period_s,
            ramp_s,
            start_up: StartUp::Standing,
            phase_offset: 0.0,
        })
    }

    /// The adult reference at `speed_m_s` (a condition of [`AdultNorms`]), with a stride
    /// period and a start-up ramp (both s).
    pub fn adult(speed_m_s: f64, stride_period_s: f64, ramp_s: f64) -> Result<Self, LegError> {
        positive("stride_period_s", stride_period_s)?;
        non_negative("ramp_s", ramp_s)?;
        let c = AdultNorms::at(speed_m_s)?;
        Ok(Self {
            hip: c.hip,
            knee: c.knee,
            ankle: Some(c.ankle),
            data_speed_m_s: Some(c.speed_m_s),
            toe_off: c.toe_off,
            stride_period_s,
            ramp_s,
            start_up: StartUp::Standing,
            phase_offset: 0.0,
        })
    }

    /// The same reference with `correction` (deg over the cycle) added to the hip: the
    /// belt-consistent stance that [`crate::fit_gait()`] finds for a trainer.
    pub fn with_hip_correction(&self, correction: &FourierSeries) -> Self {
        Self {
            hip: self.hip.plus(correction),
            ..*self
        }
    }

    /// The same reference started by `start_up`. An in-step start needs a ramp of whole
    /// strides (1e-6 s apart at most), so that it starts in double support.
    pub fn with_start_up(&self, start_up: StartUp) -> Result<Self, LegError> {
        if start_up == StartUp::InStep {
            let strides = self.ramp_s / self.stride_period_s;
            let whole = strides.round() >= 1.0
                && ((strides - strides.round()) * self.stride_period_s).abs() <= 1e-6;
            if !whole {
                return Err(invalid(
                    "gait.ramp_s",
                    self.ramp_s,
                    "must be a whole number (at least 1) of gait.stride_period_s with gait.start_up = \"in_step\" (it starts in double support)",
                ));
            }
        }
        Ok(Self { start_up, ..*self })
    }

    /// How the reference leaves standing.
    pub fn start_up(&self) -> StartUp {
        self.start_up
    }

    /// The hip's series (deg over the cycle, before the time scaling and the ramp).
    pub fn hip_series(&self) -> &FourierSeries {
        &self.hip
    }

    /// The adult data's walking speed for this reference (m/s; `None` for children's).
    pub fn data_speed_m_s(&self) -> Option<f64> {
        self.data_speed_m_s
    }

    /// Phase of toe-off in the normative cycle (0-1; phase 0 is initial contact): where
    /// Schwartz et al.'s mean ankle moment falls to zero after push-off
    /// (`tools/fit_gait.py`): 0.639 for `slow`.
    pub fn toe_off_phase(&self) -> f64 {
        self.toe_off
    }

    /// Phase of the cycle at `t_s` (0-1, 0 at each initial contact of this leg).
    pub fn phase(&self, t_s: f64) -> f64 {
        self.cycles(t_s).0.rem_euclid(1.0)
    }

    /// Cycles walked at `t_s` (from this leg's phase offset) and how they run in time. An
    /// in-step start's cadence grows with the ramp's quintic `r(t)`: the cycles are
    /// `(integral of r + ramp / 2) / period`, which is `t / period` from the ramp's end on
    /// (the quintic's integral over its ramp is half of it), so that every stride after
    /// the start-up falls where a standing start's does.
    fn cycles(&self, t_s: f64) -> (f64, Cadence) {
        let period = self.stride_period_s;
        if self.start_up == StartUp::Standing || t_s >= self.ramp_s {
            return (t_s / period + self.phase_offset, Cadence::Steady { period });
        }
        let u = (t_s / self.ramp_s).max(0.0);
        let walked_s = self.ramp_s * u.powi(4) * (2.5 - 3.0 * u + u * u);
        let (rate, d_rate, _) = pma_control::quintic_blend(u, self.ramp_s);
        (
            (walked_s + 0.5 * self.ramp_s) / period + self.phase_offset,
            Cadence::Growing {
                per_s: rate / period,
                per_s2: d_rate / period,
            },
        )
    }

    /// Whether the legs stand still at `t_s` (a standing start-up, while it lasts).
    pub fn standing(&self, t_s: f64) -> bool {
        self.start_up == StartUp::Standing && t_s < self.ramp_s
    }

    /// Whether the reference's foot is in stance at `t_s` (during a standing start-up the
    /// leg stands).
    pub fn in_stance(&self, t_s: f64) -> bool {
        self.standing(t_s) || self.phase(t_s) < self.toe_off
    }

    /// Start-up ramp (s).
    pub fn ramp_s(&self) -> f64 {
        self.ramp_s
    }

    /// When servo-driven strides are measured (`size`, `fit-gait`): after the start-up ramp
    /// (whole strides) and one stride more, so that a start-up transient (the harness's
    /// 480 N as the belt comes up to speed) is not reported as the gait's (s).
    pub fn measured_from_s(&self) -> f64 {
        let stride_s = self.stride_period_s();
        (self.ramp_s / stride_s).ceil() * stride_s + stride_s
    }

    /// How much of the cycle's motion the start-up ramp lets through at `t_s` (0 standing,
    /// 1 after the ramp).
    pub fn ramp_share(&self, t_s: f64) -> f64 {
        self.ramp(t_s).0
    }

    /// The same reference for leg `leg` of a trainer: the second leg half a stride later,
    /// started by the same ramp (both legs leave standing together).
    pub fn for_leg(&self, leg: usize) -> Self {
        Self {
            phase_offset: (self.phase_offset + 0.5 * leg as f64).rem_euclid(1.0),
            ..*self
        }
    }

    /// Where in the cycle this leg is at `t = 0` (0, or 0.5 for a trainer's second leg).
    pub fn phase_offset(&self) -> f64 {
        self.phase_offset
    }

    /// The other leg's references at `t_s`: the same cycle half a stride later, started by
    /// the same ramp (both legs leave standing together).
    pub fn sample_half_stride_later(&self, t_s: f64) -> GaitSample {
        self.for_leg(1).sample(t_s)
    }

    /// Stride period (s).
    pub fn stride_period_s(&self) -> f64 {
        self.stride_period_s
    }

    /// Quintic smoothstep of the motion's amplitude and its first two time derivatives
    /// (1 throughout an in-step start, which grows the cadence instead).
    fn ramp(&self, t: f64) -> (f64, f64, f64) {
        if self.start_up == StartUp::InStep || self.ramp_s <= 0.0 || t >= self.ramp_s {
            return (1.0, 0.0, 0.0);
        }
        if t <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        pma_control::quintic_blend(t / self.ramp_s, self.ramp_s)
    }

    fn joint(
        series: &FourierSeries,
        harmonics: &[(f64, f64); HARMONICS],
        cadence: Cadence,
        ramp: (f64, f64, f64),
    ) -> JointSample {
        let (y, dy, ddy) = series.eval(harmonics);
        // Chain rule for the cycles' time course, then the product rule for the ramp.
        let (g, dg, ddg) = match cadence {
            Cadence::Steady { period } => (y, dy / period, ddy / (period * period)),
            Cadence::Growing { per_s, per_s2 } => {
                (y, dy * per_s, ddy * per_s * per_s + dy * per_s2)
            }
        };
        let (s, ds, dds) = ramp;
        let deg = std::f64::consts::PI / 180.0;
        JointSample {
            angle_rad: s * g * deg,
            velocity_rad_s: (ds * g + s * dg) * deg,
            acceleration_rad_s2: (dds * g + 2.0 * ds * dg + s * ddg) * deg,
        }
    }

    /// The hip's and the knee's angles at `t_s` (rad), the same as [`Self::sample`]'s bit
    /// for bit, without the rates, the accelerations and the ankle: the virtual other leg
    /// asks for them at every physics substep.
    pub fn angles_rad(&self, t_s: f64) -> [f64; 2] {
        let (s, _, _) = self.ramp(t_s);
        let (cycles, _) = self.cycles(t_s);
        let harmonics = FourierSeries::harmonics(cycles);
        let deg = std::f64::consts::PI / 180.0;
        [self.hip.value(&harmonics), self.knee.value(&harmonics)].map(|g| s * g * deg)
    }

    /// References at time `t_s` (before 0: standing).
    pub fn sample(&self, t_s: f64) -> GaitSample {
        let ramp = self.ramp(t_s);
        let (cycles, cadence) = self.cycles(t_s);
        // Both joints at the same phase: one set of sines for the two.
        let harmonics = FourierSeries::harmonics(cycles);
        GaitSample {
            hip: Self::joint(&self.hip, &harmonics, cadence, ramp),
            knee: Self::joint(&self.knee, &harmonics, cadence, ramp),
            ankle: self.ankle.map_or_else(JointSample::default, |a| {
                Self::joint(&a, &harmonics, cadence, ramp)
            }),
        }
    }
}

#[cfg(test)]
mod tests;
