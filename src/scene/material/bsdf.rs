//! The BSDF interface: every scene material as one value ([`Bsdf`], its
//! variants generated from the plugin registry, one per plugin) with
//! `eval`, `pdf`, `sample`, its flags and the Lambertian part the
//! irradiance cache multiplies irradiance with. Each model lives in its
//! plugin's file beside the plugin's parameters and implements [`Model`];
//! [`Bsdf`] only dispatches.
//!
//! All directions are unit vectors in the **local frame** (z = the shading
//! normal as authored) and point away from the surface; `ω_i` below the
//! surface (`z < 0`) is transmission. Values are `f(ω_o, ω_i)` in sr⁻¹,
//! without the cosine, in the radiance convention (Veach 1997 §5.2: light
//! refracted into a denser medium is concentrated by `1/η²`).
//!
//! Surfaces are **one-sided** unless the material transmits or is
//! `twosided`, like Mitsuba 3's: seen from below, a plain BSDF is black.

use glam::{DVec2, DVec3};

use super::glossy::Phong;
use super::{Bsdf, Material};
use crate::color::Rgb;
use crate::scene::SurfaceHit;
use crate::scene::texture::Texture;
use crate::sphere::Frame;

/// What kinds of scattering a BSDF has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BsdfFlags {
    /// A Lambertian part (the irradiance cache serves it).
    pub diffuse: bool,
    /// A part spread over directions but not Lambertian (microfacets, Phong).
    pub glossy: bool,
    /// Dirac deltas (mirrors, smooth interfaces): no light sample reaches them.
    pub delta: bool,
    /// Light passes through the surface.
    pub transmission: bool,
}

impl BsdfFlags {
    pub(crate) fn union(self, other: Self) -> Self {
        Self {
            diffuse: self.diffuse || other.diffuse,
            glossy: self.glossy || other.glossy,
            delta: self.delta || other.delta,
            transmission: self.transmission || other.transmission,
        }
    }
}

/// A reflection model in the local frame (z = the shading normal), both
/// directions pointing away from the surface. The defaults are those of a
/// one-sided model with no Lambertian part whose lobes are Dirac deltas
/// (`eval` and `pdf` zero for every pair of directions).
pub trait Model {
    /// `f(ω_o, ω_i)`, sr⁻¹, without the cosine; zero for pairs only a
    /// Dirac delta connects.
    fn eval(&self, _wo: DVec3, _wi: DVec3) -> Rgb {
        Rgb::BLACK
    }

    /// Solid-angle density (sr⁻¹) with which [`Self::sample`] draws `ω_i`
    /// by its non-delta parts.
    fn pdf(&self, _wo: DVec3, _wi: DVec3) -> f64 {
        0.0
    }

    /// Draws `ω_i`: `u_lobe` picks a lobe or event, `u` drives the warp.
    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample>;

    /// The kinds of scattering the model has.
    fn flags(&self) -> BsdfFlags;

    /// The Lambertian part `ρ(ω_o)` (see [`Bsdf::lambertian`]).
    fn lambertian(&self, _wo: DVec3) -> Rgb {
        Rgb::BLACK
    }

    /// True when the model reflects nothing, so paths can stop here.
    fn is_black(&self) -> bool {
        false
    }

    /// Whether `ω_o` sees a side that scatters light at all.
    fn scatters_towards(&self, wo: DVec3) -> bool {
        self.flags().transmission || wo.z > 0.0
    }

    /// True if the model turns with the surface about its normal.
    fn is_anisotropic(&self) -> bool {
        false
    }

    /// The Phong model this is, which the cache integrates by BMC.
    fn phong(&self) -> Option<&Phong> {
        None
    }
}

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

impl Bsdf {
    /// True if the BSDF turns with the surface about its normal (a
    /// microfacet lobe with `alpha_u ≠ alpha_v`): it is then evaluated in
    /// the hit's tangent frame (`SurfaceHit::shading_frame`), every other
    /// BSDF in the frame of its normal alone.
    pub fn is_anisotropic(&self) -> bool {
        self.model().is_anisotropic()
    }

    /// The frame `hit`'s BSDF `self` is evaluated in: the tangent frame for
    /// an anisotropic one, else the normal's ([`Frame::from_normal`]), so
    /// isotropic shading is what it was before tangents existed.
    pub fn frame_at(&self, hit: &SurfaceHit) -> Frame {
        if self.is_anisotropic() {
            hit.shading_frame()
        } else {
            Frame::from_normal(hit.shading_normal)
        }
    }

    /// `f(ω_o, ω_i)`, sr⁻¹; zero for pairs only a Dirac delta connects.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.model().eval(wo, wi)
    }

    /// Solid-angle density (sr⁻¹) with which [`Self::sample`] draws `ω_i`
    /// by its non-delta parts.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.model().pdf(wo, wi)
    }

    /// Draws `ω_i`: `u_lobe` picks a lobe or event, `u` drives the warp.
    /// `None` where nothing scatters (from below a one-sided surface, or a
    /// direction the lobe's warp put where `f = 0`, which keeps estimates
    /// unbiased).
    pub fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        self.model().sample(wo, u_lobe, u)
    }

    /// The kinds of scattering of either side.
    pub fn flags(&self) -> BsdfFlags {
        self.model().flags()
    }

    /// True when the material reflects nothing, so paths can stop here.
    pub fn is_black(&self) -> bool {
        self.model().is_black()
    }

    /// Whether `ω_o` sees a side that scatters light at all (a one-sided
    /// BSDF seen from below does not).
    pub fn scatters_towards(&self, wo: DVec3) -> bool {
        self.model().scatters_towards(wo)
    }

    /// The Lambertian part `ρ(ω_o)` of the BSDF seen from `ω_o`: for every
    /// `ω_i` on `ω_o`'s side, `f(ω_o, ω_i) = ρ(ω_o)/π + r(ω_o, ω_i)`, and the
    /// irradiance cache estimates `ρ E/π` from its records while the rest
    /// `r` (possibly negative) is sampled (docs/math.md §18.3). Each
    /// model's file says what its part is (zero unless it has one).
    pub fn lambertian(&self, wo: DVec3) -> Rgb {
        self.model().lambertian(wo)
    }

    /// The Phong model behind this BSDF, which the cache integrates by
    /// BMC with its lobe as the density.
    pub fn phong(&self) -> Option<&Phong> {
        self.model().phong()
    }

    /// The BSDF of a textured `material` at `hit`; `template` is
    /// `Bsdf::from(material)`, whose precomputed tables (the plastics'
    /// coatings) are reused.
    pub fn textured(material: &Material, hit: &SurfaceHit, template: &Bsdf) -> Bsdf {
        material.build(Lookup::At(SurfacePoint::of(hit)), Some(template))
    }
}

impl From<&Material> for Bsdf {
    /// The material's BSDF with each texture at its mean: what stands for
    /// the material where no surface point is at hand, and the template
    /// that [`Bsdf::textured`] takes its precomputed tables from.
    fn from(material: &Material) -> Self {
        material.build(Lookup::Mean, None)
    }
}

/// Where a material's textures are read when its BSDF is built (pbrt-v4's
/// `GetBxDF` at a surface point, or the material as a whole).
#[derive(Clone, Copy, Debug)]
pub enum Lookup {
    /// At a surface point.
    At(SurfacePoint),
    /// Their means.
    Mean,
}

/// A surface point as a material's build step sees it: its texture
/// coordinates, and its parametrisation and geometric normal in the local
/// frame of [`SurfaceHit::shading_frame`] (z = the shading normal), which
/// bump and normal maps tilt.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub uv: DVec2,
    /// ∂p/∂u, local frame.
    pub dp_du: DVec3,
    /// ∂p/∂v, local frame.
    pub dp_dv: DVec3,
    /// The unit geometric normal of the front side, local frame.
    pub normal: DVec3,
}

impl SurfacePoint {
    /// `hit` in its shading frame.
    pub fn of(hit: &SurfaceHit) -> Self {
        let frame = hit.shading_frame();
        Self {
            uv: hit.uv,
            dp_du: frame.to_local(hit.dp_du),
            dp_dv: frame.to_local(hit.dp_dv),
            normal: frame.to_local(hit.normal),
        }
    }
}

impl Lookup {
    /// A colour texture's value, linear RGB.
    pub fn rgb(self, t: &Texture) -> Rgb {
        match self {
            Lookup::At(p) => Rgb::from_array(t.eval(p.uv)),
            Lookup::Mean => Rgb::from_array(t.mean()),
        }
    }

    /// A scalar texture's value (Mitsuba's `eval_1`).
    pub fn scalar(self, t: &Texture) -> f64 {
        match self {
            Lookup::At(p) => t.eval_scalar(p.uv),
            Lookup::Mean => t.mean_scalar(),
        }
    }
}

/// `w` seen from the other side of the surface.
pub fn flip(w: DVec3) -> DVec3 {
    DVec3::new(w.x, w.y, -w.z)
}

#[cfg(test)]
mod tests;
