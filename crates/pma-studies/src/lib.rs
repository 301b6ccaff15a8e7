//! Studies over the bench and the leg, each a set of closed-loop runs: gain tuning with
//! the firefly algorithm, sweeps (TOML grids run in parallel, sharded, resumable,
//! merged), shocks, sampled plant populations, the paper's experiments, controllers
//! compared on the leg with a patient, and the pendulum test of the patient model.
//! rayon and serde_json live here, not in the crates that run one loop.
#![warn(missing_docs)]

pub mod compare;
mod error;
pub mod experiments;
mod files;
pub mod identify;
pub mod leg_tune;
pub mod pendulum;
pub mod population;
pub mod shock;
pub mod sweep;
pub mod tune;

pub use error::StudyError;
