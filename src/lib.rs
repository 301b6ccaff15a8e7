//! Library part of the `pma-exo` package: the glue between the simulations and the Rerun
//! layer, the gait-cycle binning of `simulate --plot`, and the assembly of the `single`,
//! `simulate` and `pendulum` runs, shared by the binary, the integration tests and the
//! Python bindings (`crates/pma-py`).
pub mod setup;
pub mod strides;
#[cfg(feature = "rerun")]
pub mod viz;

/// The README's Rust example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
