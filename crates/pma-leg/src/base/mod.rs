//! The bottom layer: the legs of a trainer ([`PerLeg`]), the joints' names, the crate's
//! error, a run's fault and the 2 x 2 solve.
mod error;
mod fault;
mod legs;
mod linalg;

pub use error::*;
pub use fault::*;
pub use legs::*;
pub(crate) use linalg::solve_2x2;
