//! Library part of the `pma-exo` package: the glue between the simulations and the Rerun
//! layer, and the gait-cycle binning of `simulate --plot`, shared by the binary and the
//! integration tests.
pub mod strides;
#[cfg(feature = "rerun")]
pub mod viz;

/// The README's Rust example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
