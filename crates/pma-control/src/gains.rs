//! One gain table per controller: each gain's name (as in gain files), documentation,
//! check and search range is written once, in [`gain_table!`], and the struct, its
//! lookup by name, its validation and the tuner's search space all come from it.
use pma_model::error::{finite, non_negative, positive};
use pma_model::Invalid;

/// What a gain must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// Any finite number.
    Finite,
    /// A finite number `> 0`.
    Positive,
    /// A finite number `>= 0`.
    NonNegative,
}

impl Rule {
    /// Checks `value`, naming it `<controller> gain <name>` in the error.
    pub fn check(self, controller: &str, name: &str, value: f64) -> Result<f64, Invalid> {
        let field = format!("{controller} gain `{name}`");
        match self {
            Rule::Finite => finite(field, value),
            Rule::Positive => positive(field, value),
            Rule::NonNegative => non_negative(field, value),
        }
    }
}

/// How the tuner searches a gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Search {
    /// Not searched: the default (or the gain file's value) is kept.
    Fixed,
    /// Log scale over `[low, high]` (gains spanning decades).
    Log(f64, f64),
    /// Linear scale over `[low, high]`.
    Lin(f64, f64),
}

impl Search {
    /// The gain at `u` in `[0, 1]` of the range; `None` for a fixed gain.
    pub fn map(self, u: f64) -> Option<f64> {
        let u = u.clamp(0.0, 1.0);
        match self {
            Search::Fixed => None,
            Search::Log(lo, hi) => Some((lo.ln() + u * (hi.ln() - lo.ln())).exp()),
            Search::Lin(lo, hi) => Some(lo + u * (hi - lo)),
        }
    }
}

/// How large a gain may be before it stops describing a controller the muscle can take.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    /// None written: two decades above the top of the tuner's range (nothing beyond it is
    /// tuned or tested; a gain there is a typo or a unit slip).
    Searched,
    /// At most this value.
    At(f64),
    /// A pressure, within the command's range `0..=max` (a bias outside it holds the valve
    /// at a limit).
    Pressure,
    /// At most the pressure limit over this much input: `kp_pa_per_m` over 1 um of error
    /// (below the displacement sensor's resolution) swings the whole valve range.
    PressurePer(f64),
}

impl Bound {
    /// The largest admissible value under `limits`, for a gain searched over `search`.
    pub fn max(self, search: Search, limits: &crate::CommandLimits) -> f64 {
        match (self, search) {
            (Bound::Searched, Search::Log(_, hi) | Search::Lin(_, hi)) => 100.0 * hi,
            (Bound::Searched, Search::Fixed) => f64::INFINITY,
            (Bound::At(v), _) => v,
            (Bound::Pressure, _) => limits.max_pa,
            (Bound::PressurePer(input), _) => limits.max_pa / input,
        }
    }
}

impl Search {
    /// Where `value` lies in the range, in `[0, 1]` (clamped to the range); `None` for a
    /// fixed gain or a value the scale cannot place (not finite, not positive on a log
    /// scale).
    pub fn unmap(self, value: f64) -> Option<f64> {
        let u = match self {
            Search::Fixed => return None,
            Search::Log(lo, hi) if value > 0.0 => (value.ln() - lo.ln()) / (hi.ln() - lo.ln()),
            Search::Log(..) => return None,
            Search::Lin(lo, hi) => (value - lo) / (hi - lo),
        };
        u.is_finite().then(|| u.clamp(0.0, 1.0))
    }
}

/// One gain of a controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainSpec {
    /// Its name in gain files (with its unit).
    pub name: &'static str,
    /// What it is.
    pub doc: &'static str,
    /// What it must be.
    pub rule: Rule,
    /// How the tuner searches it.
    pub search: Search,
    /// How large it may be.
    pub bound: Bound,
}

/// A controller's gains, through its table.
pub trait GainSet {
    /// The table: every gain, in file order.
    fn specs(&self) -> &'static [GainSpec];
    /// The gain named `name`.
    fn get(&self, name: &str) -> Option<f64>;
    /// The gain named `name`, to change it.
    fn get_mut(&mut self, name: &str) -> Option<&mut f64>;
}

/// Checks every gain of `gains` against its rule.
pub fn check_rules(gains: &dyn GainSet, controller: &str) -> Result<(), Invalid> {
    for spec in gains.specs() {
        let value = gains.get(spec.name).unwrap_or(f64::NAN);
        spec.rule.check(controller, spec.name, value)?;
    }
    Ok(())
}

/// Checks every gain of `gains` against its bound under the command `limits`: what the
/// muscle behind them can take. A pressure gain (`bias_pa`) must lie in the command's
/// range, a gain in pascals per unit of input must not swing the whole range on less
/// input than the sensors resolve, and every other gain must stay within two decades of
/// what the tuner searches (or its written bound).
pub fn check_bounds(
    gains: &dyn GainSet,
    controller: &str,
    limits: &crate::CommandLimits,
) -> Result<(), Invalid> {
    for spec in gains.specs() {
        let value = gains.get(spec.name).unwrap_or(f64::NAN);
        let max = spec.bound.max(spec.search, limits);
        let min = match spec.bound {
            Bound::Pressure => 0.0,
            _ => f64::NEG_INFINITY,
        };
        if !(value >= min && value <= max) {
            let why = match spec.bound {
                Bound::Searched => format!(
                    "at most {} (two decades above the range the tuner searches and the tests cover)",
                    pma_model::error::number(max)
                ),
                Bound::At(_) => format!("at most {}", pma_model::error::number(max)),
                Bound::Pressure => format!(
                    "within the command's range 0 to {} Pa (the pressure limit)",
                    pma_model::error::number(max)
                ),
                Bound::PressurePer(input) => format!(
                    "at most {}: the pressure limit, {} Pa, over {} of input (less than the sensors resolve)",
                    pma_model::error::number(max),
                    pma_model::error::number(limits.max_pa),
                    pma_model::error::number(input)
                ),
            };
            return Err(Invalid::new(
                format!("{controller} gain `{}`", spec.name),
                value,
                format!("must be {why}"),
            ));
        }
    }
    Ok(())
}

/// Defines a gains struct from its table: each field with its documentation, its [`Rule`]
/// and optionally its [`Search`] range, e.g.
/// `kp_pa_per_m: NonNegative, Log(1e5, 1e11) => PressurePer(1e-6);` (the bound after
/// `=>` is optional, see [`Bound`]). The struct (serde with defaults and
/// unknown fields refused) and its [`GainSet`] come out of it; `Default` is written by
/// hand (the paper's or the tuned values).
#[macro_export]
macro_rules! gain_table {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:expr])*
                $field:ident: $rule:ident $(, $search:ident($lo:expr, $hi:expr))?
                    $(=> $bound:ident $(($b:expr))?)?;
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
        #[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
        pub struct $name {
            $(
                $(#[doc = $doc])*
                pub $field: f64,
            )*
        }

        impl $name {
            /// Every gain: name, documentation, rule and search range, in file order.
            pub const SPECS: &'static [$crate::gains::GainSpec] = &[
                $(
                    $crate::gains::GainSpec {
                        name: stringify!($field),
                        doc: concat!($($doc, "\n"),*),
                        rule: $crate::gains::Rule::$rule,
                        search: $crate::gain_table!(@search $($search($lo, $hi))?),
                        bound: $crate::gain_table!(@bound $($bound $(($b))?)?),
                    },
                )*
            ];
        }

        impl $crate::gains::GainSet for $name {
            fn specs(&self) -> &'static [$crate::gains::GainSpec] {
                Self::SPECS
            }
            fn get(&self, name: &str) -> Option<f64> {
                match name {
                    $(stringify!($field) => Some(self.$field),)*
                    _ => None,
                }
            }
            fn get_mut(&mut self, name: &str) -> Option<&mut f64> {
                match name {
                    $(stringify!($field) => Some(&mut self.$field),)*
                    _ => None,
                }
            }
        }
    };
    (@search) => {
        $crate::gains::Search::Fixed
    };
    (@search $kind:ident($lo:expr, $hi:expr)) => {
        $crate::gains::Search::$kind($lo, $hi)
    };
    (@bound) => {
        $crate::gains::Bound::Searched
    };
    (@bound $kind:ident) => {
        $crate::gains::Bound::$kind
    };
    (@bound $kind:ident($b:expr)) => {
        $crate::gains::Bound::$kind($b)
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unmap_inverts_map_within_the_range() {
        for s in [Search::Log(1e2, 1e6), Search::Lin(-1.0, 3.0)] {
            for u in [0.0, 0.3, 1.0] {
                let v = s.map(u).unwrap();
                assert!((s.unmap(v).unwrap() - u).abs() < 1e-12);
            }
        }
        assert_eq!(Search::Log(1.0, 10.0).unmap(1e6), Some(1.0));
        assert_eq!(Search::Log(1.0, 10.0).unmap(-1.0), None);
        assert_eq!(Search::Fixed.unmap(1.0), None);
    }

    #[test]
    fn search_ranges_map_their_ends() {
        let s = Search::Log(1e2, 1e6);
        assert!((s.map(0.0).unwrap() - 1e2).abs() < 1e-9);
        assert!((s.map(1.0).unwrap() - 1e6).abs() < 1e-3);
        assert!((s.map(0.5).unwrap() - 1e4).abs() < 1e-6);
        assert_eq!(Search::Lin(0.0, 2.0).map(0.25), Some(0.5));
        assert_eq!(Search::Fixed.map(0.5), None);
    }
}
