//! BSDF models as Mitsuba 3 names them, one per file, each opening with
//! its parameters' docs; `render::bsdf::Bsdf` dispatches to them. Every lobe works in the **local frame** (z =
//! the shading normal), both directions pointing away from the surface, and
//! offers `eval` (the BSDF value, sr⁻¹, without the cosine), `pdf` (the
//! solid-angle density its `sample` draws with) and `sample`.

pub mod conductor;
pub mod dielectric;
pub mod phong;
pub mod plastic;
pub mod rough_conductor;
pub mod rough_dielectric;
pub mod rough_plastic;
pub mod thin_dielectric;

#[cfg(test)]
mod mitsuba_agreement;

use glam::DVec3;

use crate::color::Rgb;

/// A direction drawn by a lobe's `sample`, with its BSDF value and density.
///
/// For a delta lobe (a smooth mirror or interface) `value` and `pdf` are
/// the weights of the Dirac deltas they share, so `value · |cos θ_i| / pdf`
/// is the sample's throughput as for any other lobe, while `eval` and `pdf`
/// of a delta lobe are zero for every pair of directions.
#[derive(Clone, Copy, Debug)]
pub struct LobeSample {
    /// Incident direction, local frame.
    pub wi: DVec3,
    /// `f(ω_o, ω_i)`, sr⁻¹ (not multiplied by the cosine).
    pub value: Rgb,
    /// Solid-angle density of `wi`, sr⁻¹ (a discrete probability for a
    /// delta lobe).
    pub pdf: f64,
    /// Whether `wi` was chosen by a Dirac delta (no light sample can hit
    /// it, so MIS gives it full weight).
    pub delta: bool,
}

impl LobeSample {
    /// A direction drawn from a lobe spread over directions (no delta),
    /// with the density `pdf` it was drawn with and its BSDF value
    /// (evaluated only when the density is positive); `None` where the
    /// density is zero, as for a direction the lobe's warp put where `f = 0`.
    pub fn spread(wi: DVec3, pdf: f64, value: impl FnOnce() -> Rgb) -> Option<Self> {
        (pdf > 0.0).then(|| LobeSample {
            wi,
            value: value(),
            pdf,
            delta: false,
        })
    }
}

/// `v` reflected about the unit normal `n`: `2 (v·n) n − v`.
pub fn reflect(v: DVec3, n: DVec3) -> DVec3 {
    2.0 * v.dot(n) * n - v
}
