//! Gait references: normative curves and their Fourier series, the reference a leg tracks,
//! its settings and the loading curve of a stance.
mod loading;
mod reference;
mod settings;

pub use loading::*;
pub use reference::*;
pub use settings::*;
