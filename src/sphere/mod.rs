//! Geometry of directions: local shading frames (z = surface normal) and
//! hemisphere sample sets.

mod frame;
mod sample_set;

pub use frame::Frame;
pub use sample_set::{MAX_SAMPLES, SampleSet, SampleSetKind, SampleSetSpec};
