//! Tools over scenarios: the joints' demand over a stride, the muscles' sizing and its
//! closed-loop check, the hip's fit to the belt, the impedance probe and rapier's step
//! against the leg's exact motion.
mod closed_loop;
mod demand;
mod gait_fit;
mod probe;
mod sizing;
mod step_floor;

pub use closed_loop::*;
pub use demand::*;
pub use gait_fit::*;
pub use probe::*;
pub use sizing::*;
pub use step_floor::*;
