//! A leg run: the simulation built from a scenario, stepped under its controllers, sampled.
mod build;
mod run;
mod sample;

pub use build::*;
pub use run::*;
pub use sample::*;
