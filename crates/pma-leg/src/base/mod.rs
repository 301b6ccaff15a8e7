//! The bottom layer: the legs of a trainer ([`PerLeg`]), the joints' names, the crate's
//! error and a run's fault.
mod error;
mod fault;
mod legs;

pub use error::*;
pub use fault::*;
pub use legs::*;
