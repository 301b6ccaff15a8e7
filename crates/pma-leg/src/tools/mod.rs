//! Tools over scenarios: the joints' demand over a stride, the muscles' sizing, the hip's
//! fit to the belt and the impedance probe.
mod demand;
mod gait_fit;
mod probe;
mod sizing;

pub use demand::*;
pub use gait_fit::*;
pub use probe::*;
pub use sizing::*;
