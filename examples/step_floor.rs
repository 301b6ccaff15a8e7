//! How close rapier's leg comes to its exact motion as the physics step shrinks, and where
//! its single precision stops it (issue 50, docs/convergence.md "rapier's floor";
//! `pma_leg::tools::step_floor`, whose 2 s table `cargo test --test docs_figures` checks).
//!
//! The in-air leg (`exo_leg.urdf`, fixed pelvis, no muscles) swings about a pose constant
//! joint torques hold (no joint limit reached), released 0.2 rad away, with the joints'
//! viscous damping, for `SECONDS`; its final angles against the same two-link pendulum's
//! Lagrange equations integrated by fourth-order Runge-Kutta in f64 at 1 us.
//!
//!     cargo run --release --example step_floor [-- SECONDS [DAMPING_NM_S_PER_RAD]]
use pma_leg::tools::{step_floor, STEP_FLOOR_SUBSTEPS};
use std::process::ExitCode;

fn main() -> ExitCode {
    match table() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn table() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let secs: f64 = args.next().map_or(Ok(2.0), |s| s.parse())?;
    let damping: f64 = args.next().map_or(Ok(0.5), |s| s.parse())?;
    let rows = step_floor(secs, damping, &STEP_FLOOR_SUBSTEPS)?;
    println!("{secs} s, joint damping {damping} N m s/rad, against RK4 in f64 at 1 us");
    println!(
        "| physics substeps | step (us) | hip error (rad) | knee error (rad) | energy error (J) |"
    );
    println!("|---|---|---|---|---|");
    for row in rows {
        println!("{}", row.markdown_row());
    }
    Ok(())
}
