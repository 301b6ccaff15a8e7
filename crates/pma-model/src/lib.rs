//! Pneumatic muscle actuator (PMA) models: the three-element muscle of Cao et al. 2020
//! (eq. 1, Table I), a proportional valve (ideal or first-order lag with rate limit and
//! dead time), a position sensor (range, quantisation, seeded noise) and the load.
//!
//! Conventions used everywhere in the workspace: contraction `x` in metres, positive when
//! the muscle is shorter than at rest; pressure `P` in pascals (gauge); force in newtons,
//! positive when the muscle pulls.
//!
//! ```
//! use pma_model::{DampingMode, MuscleParams};
//! let m = MuscleParams::TABLE_I;
//! // Holding a 2 kg load at 15 mm contraction needs about 0.7 bar.
//! let p = m.static_pressure_for(2.0 * pma_model::GRAVITY_M_S2, 0.015).unwrap();
//! assert!((p - 0.7e5).abs() < 0.05e5);
//! assert!(m.force(p, 0.015, 0.0, DampingMode::Inflation) > 19.0);
//! ```
#![warn(missing_docs)]

pub mod error;
pub mod festo;
mod load;
mod muscle;
pub mod pneumatics;
mod rng;
mod scale;
mod sensor;
mod valve;

pub use error::Invalid;
pub use load::{LoadProfile, LoadStep, GRAVITY_M_S2, MAX_LOAD_KG};
pub use muscle::{DampingMode, MuscleModel, MuscleParams, MAX_FACTOR_ON_TABLE_I};
pub use pneumatics::{Chamber, FlowParams, PneumaticsSettings, ValveSpec};
pub use rng::GaussianRng;
pub use scale::MuscleScale;
pub use sensor::{PositionSensor, SensorParams};
pub use valve::{Valve, ValveParams, MAX_VALVE_DELAY_S, MAX_VALVE_PRESSURE_PA};
