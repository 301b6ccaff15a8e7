//! The ground: foot-belt contact, the treadmill's settings, the sagittal chain of a leg,
//! the other leg's reference and the belt and harness as a whole.
mod belt;
mod chain;
mod contact;
mod other_leg;
mod treadmill;

pub use belt::*;
pub use chain::*;
pub use contact::*;
pub(crate) use other_leg::*;
pub use treadmill::*;
