//! Tools over scenarios: the joints' demand over a stride, the muscles' sizing and its
//! closed-loop check, the hip's fit to the belt and the impedance probe.
mod closed_loop;
mod demand;
mod gait_fit;
mod probe;
mod sizing;

pub use closed_loop::*;
pub use demand::*;
pub use gait_fit::*;
pub use probe::*;
pub use sizing::*;
