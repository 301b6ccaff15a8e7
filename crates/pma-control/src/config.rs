use crate::{
    AprcGains, AprcNdo, CommandLimits, Controller, NdoSmc, NdoSmcGains, NominalModel, Pid,
    PidGains, Psmc, PsmcGains, StaGains, SuperTwisting,
};
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// Default gains of the baselines, from the tuning procedure documented in the README
/// (`pma-exo tune`, same optimiser and budget for every controller).
pub(crate) mod tuned {
    include!("tuned_gains.rs");
}

/// The controllers this crate provides, by their command-line names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum ControllerKind {
    /// APRC with the disturbance observer (the paper's controller).
    AprcNdo,
    /// APRC without the observer (ablation).
    Aprc,
    /// Proxy-based sliding mode control.
    Psmc,
    /// NDO-based SMC with `sat`.
    NdoSmc,
    /// Super-twisting algorithm.
    Sta,
    /// PID.
    Pid,
}

impl ControllerKind {
    /// All kinds, in the paper's Table II order (with the ablation after APRC-NDO).
    pub const ALL: [ControllerKind; 6] = [
        ControllerKind::AprcNdo,
        ControllerKind::Aprc,
        ControllerKind::Psmc,
        ControllerKind::NdoSmc,
        ControllerKind::Sta,
        ControllerKind::Pid,
    ];

    /// Command-line name.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerKind::AprcNdo => "aprc-ndo",
            ControllerKind::Aprc => "aprc",
            ControllerKind::Psmc => "psmc",
            ControllerKind::NdoSmc => "ndo-smc",
            ControllerKind::Sta => "sta",
            ControllerKind::Pid => "pid",
        }
    }

    /// Default configuration of this kind.
    pub fn default_config(self) -> ControllerConfig {
        match self {
            ControllerKind::AprcNdo => ControllerConfig::AprcNdo(AprcGains::default()),
            ControllerKind::Aprc => ControllerConfig::Aprc(AprcGains::default()),
            ControllerKind::Psmc => ControllerConfig::Psmc(PsmcGains::default()),
            ControllerKind::NdoSmc => ControllerConfig::NdoSmc(NdoSmcGains::default()),
            ControllerKind::Sta => ControllerConfig::Sta(StaGains::default()),
            ControllerKind::Pid => ControllerConfig::Pid(PidGains::default()),
        }
    }
}

impl fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for ControllerKind {
    type Err = ConfigError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ControllerKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| ConfigError::UnknownController(s.to_owned()))
    }
}

/// A controller and its gains, as stored in a gain file:
///
/// ```toml
/// controller = "aprc-ndo"
/// c1_per_s = 177.4
/// proxy_mass = 5.0      # fields left out keep their defaults
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "controller", rename_all = "kebab-case")
)]
pub enum ControllerConfig {
    /// APRC-NDO.
    AprcNdo(AprcGains),
    /// APRC (no observer).
    Aprc(AprcGains),
    /// PSMC.
    Psmc(PsmcGains),
    /// NDO-SMC.
    NdoSmc(NdoSmcGains),
    /// STA.
    Sta(StaGains),
    /// PID.
    Pid(PidGains),
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig::AprcNdo(AprcGains::PAPER)
    }
}

/// Why a gain set was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// No controller of that name.
    #[error("unknown controller `{0}` (expected one of: aprc-ndo, aprc, psmc, ndo-smc, sta, pid)")]
    UnknownController(String),
    /// A gain is NaN or infinite.
    #[error("{controller} gain `{field}` is not finite ({value})")]
    NotFinite {
        /// Controller.
        controller: &'static str,
        /// Field.
        field: &'static str,
        /// Value.
        value: f64,
    },
    /// A gain is outside its range.
    #[error("{controller} gain `{field}` = {value} {expected}")]
    OutOfRange {
        /// Controller.
        controller: &'static str,
        /// Field.
        field: &'static str,
        /// Value.
        value: f64,
        /// Requirement.
        expected: &'static str,
    },
    /// A stability condition of Theorem 1/2 of the paper fails.
    #[error(
        "gain set violates the stability condition {condition} of Theorems 1-2 (value {value})"
    )]
    Theorem {
        /// The condition, as written in the paper.
        condition: &'static str,
        /// The offending quantity.
        value: f64,
    },
    /// No gain of that name.
    #[error("{controller} has no gain `{field}`")]
    UnknownGain {
        /// Controller.
        controller: &'static str,
        /// The name.
        field: String,
    },
    /// The gain file could not be parsed (the caller names the file).
    #[error("{0}")]
    Parse(String),
    /// The gain file names another controller than the one requested.
    #[error("gain file is for `{found}` but the controller requested is `{requested}`")]
    WrongController {
        /// Requested kind.
        requested: ControllerKind,
        /// Kind in the file.
        found: ControllerKind,
    },
}

struct Checker(&'static str);

impl Checker {
    fn finite(&self, field: &'static str, value: f64) -> Result<(), ConfigError> {
        if value.is_finite() {
            Ok(())
        } else {
            Err(ConfigError::NotFinite {
                controller: self.0,
                field,
                value,
            })
        }
    }
    fn positive(&self, field: &'static str, value: f64) -> Result<(), ConfigError> {
        self.finite(field, value)?;
        if value > 0.0 {
            Ok(())
        } else {
            Err(ConfigError::OutOfRange {
                controller: self.0,
                field,
                value,
                expected: "must be > 0",
            })
        }
    }
    fn non_negative(&self, field: &'static str, value: f64) -> Result<(), ConfigError> {
        self.finite(field, value)?;
        if value >= 0.0 {
            Ok(())
        } else {
            Err(ConfigError::OutOfRange {
                controller: self.0,
                field,
                value,
                expected: "must be >= 0",
            })
        }
    }
}

fn validate_aprc(c: &Checker, g: &AprcGains, with_ndo: bool) -> Result<(), ConfigError> {
    c.positive("c1_per_s", g.c1_per_s)?;
    c.positive("c2_per_s2", g.c2_per_s2)?;
    c.positive("kp_per_s2", g.kp_per_s2)?;
    c.positive("ki_per_s3", g.ki_per_s3)?;
    c.positive("kd_per_s", g.kd_per_s)?;
    if with_ndo {
        c.positive("kappa_per_s", g.kappa_per_s)?;
    } else {
        c.finite("kappa_per_s", g.kappa_per_s)?;
    }
    c.non_negative("gamma", g.gamma)?;
    c.non_negative("boundary_layer_m_s", g.boundary_layer_m_s)?;
    c.non_negative("gain_initial", g.gain_initial)?;
    c.positive("estimator_bandwidth_rad_s", g.estimator_bandwidth_rad_s)?;
    c.finite("proxy_mass", g.proxy_mass)?;
    if g.proxy_mass <= 0.0 {
        return Err(ConfigError::Theorem {
            condition: "`m_p > 0`",
            value: g.proxy_mass,
        });
    }
    if !g.k_c_positive_definite() {
        let k = g.k_c();
        return Err(ConfigError::Theorem {
            condition: "`K_c positive definite` (det K_c > 0, K_c11 > 0)",
            value: k[0][0] * k[1][1] - k[0][1] * k[1][0],
        });
    }
    if g.varpi() <= 0.0 {
        return Err(ConfigError::Theorem {
            condition: "`varpi = Kp c1 - Ki - Kd c2 > 0`",
            value: g.varpi(),
        });
    }
    Ok(())
}

impl ControllerConfig {
    /// Kind of controller.
    pub fn kind(&self) -> ControllerKind {
        match self {
            ControllerConfig::AprcNdo(_) => ControllerKind::AprcNdo,
            ControllerConfig::Aprc(_) => ControllerKind::Aprc,
            ControllerConfig::Psmc(_) => ControllerKind::Psmc,
            ControllerConfig::NdoSmc(_) => ControllerKind::NdoSmc,
            ControllerConfig::Sta(_) => ControllerKind::Sta,
            ControllerConfig::Pid(_) => ControllerKind::Pid,
        }
    }

    /// The gain named `field` (as in gain files), if this controller has it.
    pub fn gain_mut(&mut self, field: &str) -> Option<&mut f64> {
        Some(match self {
            ControllerConfig::AprcNdo(g) | ControllerConfig::Aprc(g) => match field {
                "c1_per_s" => &mut g.c1_per_s,
                "c2_per_s2" => &mut g.c2_per_s2,
                "kp_per_s2" => &mut g.kp_per_s2,
                "ki_per_s3" => &mut g.ki_per_s3,
                "kd_per_s" => &mut g.kd_per_s,
                "kappa_per_s" => &mut g.kappa_per_s,
                "gamma" => &mut g.gamma,
                "proxy_mass" => &mut g.proxy_mass,
                "boundary_layer_m_s" => &mut g.boundary_layer_m_s,
                "gain_initial" => &mut g.gain_initial,
                "estimator_bandwidth_rad_s" => &mut g.estimator_bandwidth_rad_s,
                _ => return None,
            },
            ControllerConfig::Psmc(g) => match field {
                "kp_pa_per_m" => &mut g.kp_pa_per_m,
                "ki_pa_per_m_s" => &mut g.ki_pa_per_m_s,
                "kd_pa_s_per_m" => &mut g.kd_pa_s_per_m,
                "h_s" => &mut g.h_s,
                "force_max_pa" => &mut g.force_max_pa,
                "bias_pa" => &mut g.bias_pa,
                "estimator_bandwidth_rad_s" => &mut g.estimator_bandwidth_rad_s,
                _ => return None,
            },
            ControllerConfig::NdoSmc(g) => match field {
                "c1_per_s" => &mut g.c1_per_s,
                "c2_per_s2" => &mut g.c2_per_s2,
                "k_per_s" => &mut g.k_per_s,
                "eta_m_s2" => &mut g.eta_m_s2,
                "phi_m_s" => &mut g.phi_m_s,
                "kappa_per_s" => &mut g.kappa_per_s,
                "estimator_bandwidth_rad_s" => &mut g.estimator_bandwidth_rad_s,
                _ => return None,
            },
            ControllerConfig::Sta(g) => match field {
                "c1_per_s" => &mut g.c1_per_s,
                "k1" => &mut g.k1,
                "k2" => &mut g.k2,
                "estimator_bandwidth_rad_s" => &mut g.estimator_bandwidth_rad_s,
                _ => return None,
            },
            ControllerConfig::Pid(g) => match field {
                "kp_pa_per_m" => &mut g.kp_pa_per_m,
                "ki_pa_per_m_s" => &mut g.ki_pa_per_m_s,
                "kd_pa_s_per_m" => &mut g.kd_pa_s_per_m,
                "bias_pa" => &mut g.bias_pa,
                "estimator_bandwidth_rad_s" => &mut g.estimator_bandwidth_rad_s,
                _ => return None,
            },
        })
    }

    /// Sets the gain named `field`; an unknown name is an error naming it.
    pub fn set_gain(&mut self, field: &str, value: f64) -> Result<(), ConfigError> {
        let kind = self.kind();
        match self.gain_mut(field) {
            Some(g) => {
                *g = value;
                Ok(())
            }
            None => Err(ConfigError::UnknownGain {
                controller: kind.as_str(),
                field: field.to_owned(),
            }),
        }
    }

    /// Checks every gain: finite, signs, and for APRC(-NDO) the conditions of Theorems 1
    /// and 2 (`m_p > 0`, `K_c` positive definite, `varpi > 0`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let c = Checker(self.kind().as_str());
        match self {
            ControllerConfig::AprcNdo(g) => validate_aprc(&c, g, true),
            ControllerConfig::Aprc(g) => validate_aprc(&c, g, false),
            ControllerConfig::Psmc(g) => {
                c.non_negative("kp_pa_per_m", g.kp_pa_per_m)?;
                c.non_negative("ki_pa_per_m_s", g.ki_pa_per_m_s)?;
                c.non_negative("kd_pa_s_per_m", g.kd_pa_s_per_m)?;
                c.positive("kp + kd", g.kp_pa_per_m + g.kd_pa_s_per_m)?;
                c.non_negative("h_s", g.h_s)?;
                c.positive("force_max_pa", g.force_max_pa)?;
                c.finite("bias_pa", g.bias_pa)?;
                c.positive("estimator_bandwidth_rad_s", g.estimator_bandwidth_rad_s)
            }
            ControllerConfig::NdoSmc(g) => {
                c.positive("c1_per_s", g.c1_per_s)?;
                c.non_negative("c2_per_s2", g.c2_per_s2)?;
                c.non_negative("k_per_s", g.k_per_s)?;
                c.non_negative("eta_m_s2", g.eta_m_s2)?;
                c.positive("phi_m_s", g.phi_m_s)?;
                c.positive("kappa_per_s", g.kappa_per_s)?;
                c.positive("estimator_bandwidth_rad_s", g.estimator_bandwidth_rad_s)
            }
            ControllerConfig::Sta(g) => {
                c.positive("c1_per_s", g.c1_per_s)?;
                c.non_negative("k1", g.k1)?;
                c.non_negative("k2", g.k2)?;
                c.positive("estimator_bandwidth_rad_s", g.estimator_bandwidth_rad_s)
            }
            ControllerConfig::Pid(g) => {
                c.non_negative("kp_pa_per_m", g.kp_pa_per_m)?;
                c.non_negative("ki_pa_per_m_s", g.ki_pa_per_m_s)?;
                c.non_negative("kd_pa_s_per_m", g.kd_pa_s_per_m)?;
                c.finite("bias_pa", g.bias_pa)?;
                c.positive("estimator_bandwidth_rad_s", g.estimator_bandwidth_rad_s)
            }
        }
    }

    /// Parses and validates a gain file.
    #[cfg(feature = "serde")]
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let cfg: ControllerConfig = toml::from_str(text)
            .map_err(|e| ConfigError::Parse(crate::text::toml_error(text, &e)))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// The gain file text of this configuration.
    #[cfg(feature = "serde")]
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# could not serialise gains: {e}\n"))
    }
}

/// Validates `config` and builds the controller.
pub fn build_controller(
    config: &ControllerConfig,
    model: NominalModel,
    limits: CommandLimits,
) -> Result<Box<dyn Controller>, ConfigError> {
    config.validate()?;
    Ok(match *config {
        ControllerConfig::AprcNdo(g) => Box::new(AprcNdo::new(g, model, limits, true)),
        ControllerConfig::Aprc(g) => Box::new(AprcNdo::new(g, model, limits, false)),
        ControllerConfig::Psmc(g) => Box::new(Psmc::new(g, model, limits)),
        ControllerConfig::NdoSmc(g) => Box::new(NdoSmc::new(g, model, limits)),
        ControllerConfig::Sta(g) => Box::new(SuperTwisting::new(g, model, limits)),
        ControllerConfig::Pid(g) => Box::new(Pid::new(g, model, limits)),
    })
}

#[cfg(all(test, feature = "serde"))]
mod tests {
    use super::*;

    #[test]
    fn paper_gain_file_round_trips() {
        let text = ControllerConfig::default().to_toml_string();
        assert!(text.contains("controller = \"aprc-ndo\""), "{text}");
        assert_eq!(
            ControllerConfig::from_toml_str(&text).unwrap(),
            ControllerConfig::default()
        );
    }

    #[test]
    fn partial_file_keeps_defaults() {
        let cfg =
            ControllerConfig::from_toml_str("controller = \"aprc\"\nproxy_mass = 5.0\n").unwrap();
        match cfg {
            ControllerConfig::Aprc(g) => {
                assert_eq!(g.proxy_mass, 5.0);
                assert_eq!(g.c1_per_s, 177.4);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn unknown_field_is_rejected_with_its_name() {
        let e =
            ControllerConfig::from_toml_str("controller = \"aprc-ndo\"\nkp = 3.0\n").unwrap_err();
        assert!(e.to_string().contains("kp"), "{e}");
    }

    #[test]
    fn nan_gain_is_rejected_with_its_name() {
        let e = ControllerConfig::from_toml_str("controller = \"pid\"\nkp_pa_per_m = nan\n")
            .unwrap_err();
        assert!(
            matches!(
                e,
                ConfigError::NotFinite {
                    field: "kp_pa_per_m",
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn theorem_violations_name_the_condition() {
        let e = ControllerConfig::from_toml_str("controller = \"aprc-ndo\"\nproxy_mass = 0.0\n")
            .unwrap_err();
        assert!(e.to_string().contains("m_p > 0"), "{e}");
        // varpi = Kp c1 - Ki - Kd c2 < 0 with K_c still positive definite.
        let e = ControllerConfig::from_toml_str("controller = \"aprc-ndo\"\nkp_per_s2 = 10.0\n")
            .unwrap_err();
        assert!(e.to_string().contains("varpi"), "{e}");
    }

    #[test]
    fn unknown_controller_is_named() {
        let e = "lqr".parse::<ControllerKind>().unwrap_err();
        assert!(e.to_string().contains("lqr"));
        assert!(ControllerConfig::from_toml_str("controller = \"lqr\"\n").is_err());
    }
}
