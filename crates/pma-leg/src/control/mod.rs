//! Control of the leg: the modes and their settings, the gains, the muscle pairs and their
//! co-contraction, the path tunnel, feed-forward moments, impedance and admittance laws,
//! phase synchronisation and the leg's and trainer's controllers.
mod admittance;
mod controllers;
mod feedforward;
mod force_limit;
mod gains;
mod impedance;
mod law;
mod mode;
mod pair;
mod path;
mod phase_sync;
mod settings;

pub use admittance::*;
pub use controllers::*;
pub use feedforward::*;
pub use force_limit::*;
pub use gains::*;
pub use impedance::*;
pub use law::*;
pub use mode::*;
pub use pair::*;
pub use path::*;
pub use phase_sync::*;
pub use settings::*;
