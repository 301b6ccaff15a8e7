//! Simulation of one pneumatic muscle lifting a load (the paper's bench), the plant
//! presets (`ideal`, `mismatch`, `realistic`), the closed-loop runner shared by every
//! command, the paper's experiments, and the gain tuner.
//!
//! ```
//! use pma_control::{ControllerKind, SineReference};
//! use pma_sim::{run_single, PlantConfig, RunSpec};
//! let plant = PlantConfig::preset("ideal").unwrap();
//! let spec = RunSpec { duration_s: 2.0, ..RunSpec::default() };
//! let res = run_single(&ControllerKind::AprcNdo.default_config(), &plant,
//!                      &SineReference::paper(), &spec, &mut ()).unwrap();
//! assert!(res.stats.rte_percent < 1.0);
//! ```
#![warn(missing_docs)]

mod bench;
mod error;
pub mod experiments;
pub mod gait;
mod plant;
pub mod population;
mod run;
pub mod shock;
pub mod sweep;
pub mod tune;

pub use bench::{BenchState, Disturbance, MuscleBench};
pub use error::SimError;
pub use plant::{MuscleScale, NominalSpec, PlantConfig, PRESET_NAMES};
pub use run::{run_single, run_single_until, RunResult, RunSpec, Sample, Samples};
