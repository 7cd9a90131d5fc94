//! BSDF plugins as Mitsuba 3 names them, one per file, each opening with
//! its parameters' docs; this module grows into the scene model's BSDFs
//! (issue: real materials). Every lobe works in the **local frame** (z =
//! the shading normal), both directions pointing away from the surface, and
//! offers `eval` (the BSDF value, sr⁻¹, without the cosine), `pdf` (the
//! solid-angle density its `sample` draws with) and `sample`.

pub mod ior;
pub mod rough_conductor;
pub mod rough_dielectric;

use glam::DVec3;

use super::rgb::Rgb;

/// A direction drawn by a lobe's `sample`, with its BSDF value and density.
#[derive(Clone, Copy, Debug)]
pub struct LobeSample {
    /// Incident direction, local frame.
    pub wi: DVec3,
    /// `f(ω_o, ω_i)`, sr⁻¹ (not multiplied by the cosine).
    pub value: Rgb,
    /// Solid-angle density of `wi`, sr⁻¹.
    pub pdf: f64,
}

/// `v` reflected about the unit normal `n`: `2 (v·n) n − v`.
pub fn reflect(v: DVec3, n: DVec3) -> DVec3 {
    2.0 * v.dot(n) * n - v
}
