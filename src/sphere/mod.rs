//! Geometry of directions: local shading frames (z = surface normal).

pub mod frame;

pub use frame::Frame;
