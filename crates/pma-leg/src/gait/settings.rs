use crate::base::{invalid, LegError};
use crate::gait::{FourierSeries, GaitData, GaitReference, GaitSpeed, StartUp};
use serde::Deserialize;

/// Gait reference.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaitSettings {
    /// The normative data: `schwartz2008` (children, the default) or `fukuchi2018`
    /// (adults on a treadmill).
    #[serde(default)]
    pub data: GaitData,
    /// Speed class of the children's data whose curve shape is used (default `slow`).
    #[serde(default)]
    pub speed: Option<GaitSpeed>,
    /// Treadmill speed of the adults' data (m/s): one of its conditions.
    #[serde(default)]
    pub speed_m_per_s: Option<f64>,
    /// Stride period (s).
    pub stride_period_s: f64,
    /// Smooth start from standing (s).
    pub ramp_s: f64,
    /// How the legs leave standing over `ramp_s`: `standing` (default; straight legs, the
    /// motion grown) or `in_step` (the gait's posture, its cadence grown with the belt).
    #[serde(default)]
    pub start_up: StartUp,
    /// Added to the hip's curve (deg over the cycle, a Fourier series like the data's):
    /// the stance made consistent with a trainer's belt, as `pma-exo fit-gait` finds it
    /// for this scenario's legs, feet and belt (absent: the data's hip as measured).
    #[serde(default)]
    pub hip_correction: Option<FourierSeries>,
}

/// Largest coefficient of a hip correction (deg): a correction moves the stance by a few
/// degrees; anything larger is another gait, not the data's.
pub const HIP_CORRECTION_MAX_DEG: f64 = 10.0;

impl GaitSettings {
    /// The reference's name as outputs show it (`slow`, `adult 0.50 m/s`).
    pub fn speed_label(&self) -> String {
        match (self.data, self.speed_m_per_s) {
            (GaitData::Fukuchi2018, Some(v)) => format!("adult {v:.2} m/s"),
            _ => self.speed.unwrap_or_default().to_string(),
        }
    }

    /// The reference these settings describe (the first leg's; see
    /// [`GaitReference::for_leg`]).
    pub fn reference(&self) -> Result<GaitReference, LegError> {
        match (self.data, self.speed, self.speed_m_per_s) {
            (GaitData::Schwartz2008, _, Some(_)) => Err(invalid(
                "gait.speed_m_per_s",
                self.speed_m_per_s.unwrap_or(f64::NAN),
                "is for gait.data = \"fukuchi2018\" (adults); the children's data takes gait.speed (very-slow ... very-fast)",
            )),
            (GaitData::Schwartz2008, speed, None) => GaitReference::normative(
                speed.unwrap_or_default(),
                self.stride_period_s,
                self.ramp_s,
            ),
            (GaitData::Fukuchi2018, Some(s), _) => Err(LegError::Unsupported {
                name: "gait.speed".into(),
                value: format!("\"{s}\""),
                message: "is a speed class of the children's data: the adults' (gait.data = \"fukuchi2018\") take gait.speed_m_per_s".into(),
            }),
            (GaitData::Fukuchi2018, None, None) => Err(LegError::Missing {
                name: "gait.speed_m_per_s".into(),
                hint: "gait.data = \"fukuchi2018\" needs one of its treadmill speeds",
            }),
            (GaitData::Fukuchi2018, None, Some(v)) => {
                GaitReference::adult(v, self.stride_period_s, self.ramp_s)
            }
        }
        .and_then(|g| self.corrected(g))
        .and_then(|g| g.with_start_up(self.start_up))
    }

    /// `g` with the hip correction added, once it is checked.
    fn corrected(&self, g: GaitReference) -> Result<GaitReference, LegError> {
        let Some(c) = &self.hip_correction else {
            return Ok(g);
        };
        let largest = c.largest_coefficient_deg();
        let finite = c.cos_deg.iter().chain(&c.sin_deg).all(|v| v.is_finite());
        if !finite || largest > HIP_CORRECTION_MAX_DEG {
            return Err(invalid(
                "gait.hip_correction",
                if finite { largest } else { f64::NAN },
                "coefficients must be finite and at most 10 deg (a correction of the stance, as `pma-exo fit-gait` gives)",
            ));
        }
        if c.sin_deg[0] != 0.0 {
            return Err(invalid(
                "gait.hip_correction.sin_deg[0]",
                c.sin_deg[0],
                "must be 0 (the constant term is cos_deg[0])",
            ));
        }
        Ok(g.with_hip_correction(c))
    }
}
