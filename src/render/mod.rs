//! Light transport: reflection models, light sampling, incident radiance
//! along a ray and irradiance at points. Knows scenes, never HTTP.
//!
//! Conventions shared by every file here: radiance in W/(m²·sr) and
//! irradiance in W/m², per linear RGB channel ([`Rgb`]); local frames have
//! z = surface normal ([`crate::sphere::Frame`]); surfaces reflect and emit on
//! their front side only, as in Mitsuba 3 (see `bsdf`).

pub mod bsdf;
pub mod distribution;
pub mod polygon;
pub mod rgb;
pub mod warp;

pub use bsdf::{Bsdf, BsdfSample};
pub use rgb::Rgb;
