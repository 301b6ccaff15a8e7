//! The paper's bench (Fig. 3): one pneumatic muscle lifting a load, as a backend of the
//! closed loop (`pma-loop`); the plant presets (`ideal`, `mismatch`, `realistic`,
//! `realistic_known_lag`) and plant files; and the closed-loop runner of a controller on
//! it.
//!
//! ```
//! use pma_control::{ControllerKind, SineReference};
//! use pma_bench::{run_single, PlantConfig, RunSpec};
//! let plant = PlantConfig::preset("ideal").unwrap();
//! let spec = RunSpec { duration_s: 2.0, ..RunSpec::default() };
//! let res = run_single(&ControllerKind::AprcNdo.default_config(), &plant,
//!                      &SineReference::paper(), &spec, &mut ()).unwrap();
//! assert!(res.stats.rte_percent < 1.0);
//! ```
#![warn(missing_docs)]

mod bench;
mod error;
mod plant;
mod run;

pub use bench::{held_pressure_step, BenchState, Disturbance, MuscleBench};
pub use error::SimError;
pub use plant::{PlantConfig, PRESET_NAMES};
pub use run::{
    run_single, run_single_until, RunResult, RunSpec, Sample, Samples, MIN_PERIODS, PERIOD_RANGE_S,
};
