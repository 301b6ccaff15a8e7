use crate::base::LegError;
use pma_model::error::within;
use pma_model::festo::{DmspSize, FestoMuscle};
use serde::Deserialize;

/// Which way a muscle pulls the joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Flexion contracts it.
    Flexor,
    /// Flexion stretches it.
    Extensor,
}

impl Side {
    /// `+1` for a flexor, `-1` for an extensor.
    pub fn sign(self) -> f64 {
        match self {
            Side::Flexor => 1.0,
            Side::Extensor => -1.0,
        }
    }
}

/// One muscle's geometry (see `crates/pma-leg/models/muscles.toml`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MuscleGeometry {
    /// Unique name.
    pub name: String,
    /// URDF joint it acts on.
    pub joint: String,
    /// Flexor or extensor.
    pub side: Side,
    /// URDF link along which the muscle body lies (one of the joint's two links).
    pub body_link: String,
    /// Anchor of the muscle body in `body_link`'s frame (m).
    #[serde(deserialize_with = "pma_model::error::exact::array")]
    pub anchor_m: [f64; 3],
    /// Pulley radius at the joint (m): the moment arm.
    pub pulley_radius_m: f64,
    /// Contraction at zero joint angle (m).
    pub contraction_at_zero_m: f64,
    /// A Festo size (`dmsp-10`, `dmsp-20`, `dmsp-40`): the muscle's force is that size's
    /// measured map ([`pma_model::festo`]); absent: Table I (eq. 1).
    #[serde(default)]
    pub size: Option<DmspSize>,
    /// Nominal length of a Festo muscle (m), with `size`.
    #[serde(default)]
    pub rest_length_m: Option<f64>,
}

impl MuscleGeometry {
    /// The Festo muscle this geometry names, if it names one.
    pub fn festo(&self) -> Result<Option<FestoMuscle>, LegError> {
        let err = |message: &str| LegError::Muscle {
            muscle: self.name.clone(),
            message: message.into(),
        };
        match (self.size, self.rest_length_m) {
            (None, None) => Ok(None),
            (Some(size), Some(length)) => FestoMuscle::new(size, length)
                .map(Some)
                .map_err(|e| LegError::from(e.within_section(&self.name))),
            (Some(_), None) => Err(err("has a `size` but no `rest_length_m`")),
            (None, Some(_)) => Err(err(
                "has a `rest_length_m` but no `size` (dmsp-10, dmsp-20 or dmsp-40)",
            )),
        }
    }

    /// Contraction (m) at joint angle `theta_rad`.
    pub fn contraction(&self, theta_rad: f64) -> f64 {
        self.contraction_at_zero_m + self.moment_arm_m() * theta_rad
    }

    /// Signed moment arm (m): contraction per radian of flexion, `+r` for a flexor and
    /// `-r` for an extensor.
    pub fn moment_arm_m(&self) -> f64 {
        self.side.sign() * self.pulley_radius_m
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MuscleFile {
    muscles: Vec<MuscleGeometry>,
}

/// Plausible pulley radii (m): from a 5 mm cable drum to a 200 mm lever.
pub const PULLEY_RADIUS_RANGE_M: (f64, f64) = (0.005, 0.2);

/// Parses a muscle geometry file; `file` names it in errors.
pub fn parse_muscles(text: &str, file: &str) -> Result<Vec<MuscleGeometry>, LegError> {
    let f: MuscleFile = toml::from_str(text).map_err(|e| LegError::Parse {
        file: file.to_owned(),
        message: pma_control::text::toml_error(text, &e),
    })?;
    check_muscles(&f).map_err(|e| e.in_file(file))?;
    Ok(f.muscles)
}

fn check_muscles(f: &MuscleFile) -> Result<(), LegError> {
    for (i, m) in f.muscles.iter().enumerate() {
        if f.muscles[..i].iter().any(|o| o.name == m.name) {
            return Err(LegError::Muscle {
                muscle: m.name.clone(),
                message: "appears twice: muscle names must be unique".into(),
            });
        }
        within(
            format!("{}.pulley_radius_m", m.name),
            m.pulley_radius_m,
            PULLEY_RADIUS_RANGE_M.0,
            PULLEY_RADIUS_RANGE_M.1,
            "must be 0.005 to 0.2 m (an exoskeleton's pulley or lever arm)",
        )?;
        if !m.contraction_at_zero_m.is_finite() || m.anchor_m.iter().any(|v| !v.is_finite()) {
            return Err(LegError::Muscle {
                muscle: m.name.clone(),
                message: "contraction_at_zero_m and anchor_m must be finite".into(),
            });
        }
        m.festo()?;
    }
    Ok(())
}
