//! What a run measured: the recorder trait, then tracking, safety, stance and cooperation
//! recorders, the report of a leg and the walking verdict.
mod cooperative;
mod recorder;
mod report;
mod safety;
mod stance;
mod tracking;
mod verdict;

pub use cooperative::*;
pub use recorder::*;
pub use report::*;
pub use safety::*;
pub use stance::*;
pub use tracking::*;
pub use verdict::*;
