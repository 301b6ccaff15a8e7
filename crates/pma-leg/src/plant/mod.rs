//! The leg as a plant: each muscle on its pulley, the cuffs and sensors and their settings,
//! the supervised backend a controller drives.
mod actuator;
mod cuffs;
mod leg;
mod muscles;
mod settings;

pub use actuator::*;
pub use cuffs::*;
pub use leg::*;
pub use muscles::*;
pub use settings::*;
