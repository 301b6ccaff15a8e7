//! Library part of the `pma-exo` package: the glue between the simulations and the Rerun
//! layer, the gait-cycle binning of `simulate --plot`, and the assembly of the `single`,
//! `simulate` and `pendulum` runs and the trainer's envelope, shared by the binary, the integration tests and the
//! Python bindings (`crates/pma-py`).
pub mod envelope;
pub mod setup;
pub mod strides;
#[cfg(feature = "rerun")]
pub mod viz;

/// One line: the error and its causes, a cause left out when the message before it
/// already says it (errors that name their file wrap and print their cause). The CLI
/// prints it after `error: `; the Python bindings raise it.
pub fn error_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain().map(|c| c.to_string()) {
        if line.contains(&cause) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&cause);
    }
    pma_control::text::one_line(&line)
}

/// The README's Rust example, compiled and run by `cargo test --doc`.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
