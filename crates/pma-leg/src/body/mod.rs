//! The exoskeleton's body: its URDF, the links' inertia, the rapier multibody of one or two
//! legs on a pelvis, and the joints' settings.
mod exoskeleton;
mod inertia;
mod joints;
mod settings;
mod urdf;

pub use exoskeleton::*;
pub use inertia::*;
pub use joints::*;
pub use settings::*;
pub use urdf::*;
