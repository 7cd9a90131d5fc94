//! The BSDF interface: every scene material as one value with `eval`,
//! `pdf`, `sample`, its flags and the Lambertian part the irradiance cache
//! multiplies irradiance with. Each model lives in its own file of
//! `render::bsdfs` (Mitsuba 3's plugin names); this enum only dispatches.
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

mod blend;
mod mask;

pub use super::bsdfs::LobeSample;
use super::bsdfs::conductor::Conductor;
use super::bsdfs::dielectric::Dielectric;
use super::bsdfs::phong::Phong;
use super::bsdfs::plastic::Plastic;
use super::bsdfs::rough_conductor::RoughConductor;
use super::bsdfs::rough_dielectric::RoughDielectric;
use super::bsdfs::rough_plastic::RoughPlastic;
use super::bsdfs::thin_dielectric::ThinDielectric;
use super::microfacet::{MIN_ALPHA, Microfacet, MicrofacetKind};
use crate::color::Rgb;
use crate::scene::Material;
use crate::scene::material::{Distribution, Roughness};
use crate::scene::texture::Texture;
use crate::sphere::Frame;
pub use blend::Blend;
pub use mask::Mask;

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

/// A surface's BSDF; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambert plus a normalised Phong lobe (the JSON `diffuse` and `glossy`).
    Phong(Phong),
    Conductor(Conductor),
    RoughConductor(RoughConductor),
    Dielectric(Dielectric),
    ThinDielectric(ThinDielectric),
    RoughDielectric(RoughDielectric),
    Plastic(Plastic),
    RoughPlastic(RoughPlastic),
    /// `[front, back]`: the back BSDF sees the surface turned around.
    TwoSided(Box<[Bsdf; 2]>),
    Blend(Box<Blend>),
    Mask(Box<Mask>),
}

/// `w` seen from the other side of the surface.
fn flip(w: DVec3) -> DVec3 {
    DVec3::new(w.x, w.y, -w.z)
}

impl Bsdf {
    /// True if the BSDF turns with the surface about its normal (a
    /// microfacet lobe with `alpha_u ≠ alpha_v`): it is then evaluated in
    /// the hit's tangent frame (`SurfaceHit::shading_frame`), every other
    /// BSDF in the frame of its normal alone.
    pub fn is_anisotropic(&self) -> bool {
        let uneven = |m: &Microfacet| {
            let (u, v) = m.alpha();
            u != v
        };
        match self {
            Bsdf::RoughConductor(b) => uneven(&b.distribution),
            Bsdf::RoughDielectric(b) => uneven(&b.distribution),
            Bsdf::TwoSided(sides) => sides.iter().any(Bsdf::is_anisotropic),
            Bsdf::Blend(b) => b.bsdfs.iter().any(Bsdf::is_anisotropic),
            Bsdf::Mask(m) => m.bsdf.is_anisotropic(),
            _ => false,
        }
    }

    /// The frame `hit`'s BSDF `self` is evaluated in: the tangent frame for
    /// an anisotropic one, else the normal's ([`Frame::from_normal`]), so
    /// isotropic shading is what it was before tangents existed.
    pub fn frame_at(&self, hit: &crate::scene::SurfaceHit) -> Frame {
        if self.is_anisotropic() {
            hit.shading_frame()
        } else {
            Frame::from_normal(hit.shading_normal)
        }
    }

    /// For a two-sided BSDF, the side `wo` sees and whether directions
    /// must be turned around for it; the BSDF itself otherwise.
    fn side(&self, wo: DVec3) -> (&Bsdf, bool) {
        match self {
            Bsdf::TwoSided(sides) if wo.z < 0.0 => (&sides[1], true),
            Bsdf::TwoSided(sides) => (&sides[0], false),
            other => (other, false),
        }
    }

    /// `f(ω_o, ω_i)`, sr⁻¹; zero for pairs only a Dirac delta connects.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        match self.side(wo) {
            (side, true) => side.eval(flip(wo), flip(wi)),
            (Bsdf::Phong(b), _) => b.eval(wo, wi),
            (Bsdf::RoughConductor(b), _) => b.eval(wo, wi),
            (Bsdf::RoughDielectric(b), _) => b.eval(wo, wi),
            (Bsdf::Plastic(b), _) => b.eval(wo, wi),
            (Bsdf::RoughPlastic(b), _) => b.eval(wo, wi),
            (Bsdf::Blend(b), _) => b.eval(wo, wi),
            (Bsdf::Mask(b), _) => b.eval(wo, wi),
            (Bsdf::Conductor(_) | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_), _) => Rgb::BLACK,
            (Bsdf::TwoSided(_), _) => unreachable!("side() resolves two-sided BSDFs"),
        }
    }

    /// Solid-angle density (sr⁻¹) with which [`Self::sample`] draws `ω_i`
    /// by its non-delta parts.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        match self.side(wo) {
            (side, true) => side.pdf(flip(wo), flip(wi)),
            (Bsdf::Phong(b), _) => b.pdf(wo, wi),
            (Bsdf::RoughConductor(b), _) => b.pdf(wo, wi),
            (Bsdf::RoughDielectric(b), _) => b.pdf(wo, wi),
            (Bsdf::Plastic(b), _) => b.pdf(wo, wi),
            (Bsdf::RoughPlastic(b), _) => b.pdf(wo, wi),
            (Bsdf::Blend(b), _) => b.pdf(wo, wi),
            (Bsdf::Mask(b), _) => b.pdf(wo, wi),
            (Bsdf::Conductor(_) | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_), _) => 0.0,
            (Bsdf::TwoSided(_), _) => unreachable!("side() resolves two-sided BSDFs"),
        }
    }

    /// Draws `ω_i`: `u_lobe` picks a lobe or event, `u` drives the warp.
    /// `None` where nothing scatters (from below a one-sided surface, or a
    /// direction the lobe's warp put where `f = 0`, which keeps estimates
    /// unbiased).
    pub fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        match self.side(wo) {
            (side, true) => side.sample(flip(wo), u_lobe, u).map(|s| LobeSample {
                wi: flip(s.wi),
                ..s
            }),
            (Bsdf::Phong(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::Conductor(b), _) => b.sample(wo),
            (Bsdf::RoughConductor(b), _) => b.sample(wo, u),
            (Bsdf::Dielectric(b), _) => b.sample(wo, u_lobe),
            (Bsdf::ThinDielectric(b), _) => b.sample(wo, u_lobe),
            (Bsdf::RoughDielectric(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::Plastic(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::RoughPlastic(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::Blend(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::Mask(b), _) => b.sample(wo, u_lobe, u),
            (Bsdf::TwoSided(_), _) => unreachable!("side() resolves two-sided BSDFs"),
        }
    }

    /// The kinds of scattering of either side.
    pub fn flags(&self) -> BsdfFlags {
        let none = BsdfFlags::default();
        match self {
            Bsdf::Phong(b) => BsdfFlags {
                diffuse: !b.diffuse.is_black(),
                glossy: !b.specular.is_black(),
                ..none
            },
            Bsdf::Conductor(_) => BsdfFlags {
                delta: true,
                ..none
            },
            Bsdf::RoughConductor(_) => BsdfFlags {
                glossy: true,
                ..none
            },
            Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) => BsdfFlags {
                delta: true,
                transmission: true,
                ..none
            },
            Bsdf::RoughDielectric(_) => BsdfFlags {
                glossy: true,
                transmission: true,
                ..none
            },
            Bsdf::Plastic(_) => BsdfFlags {
                diffuse: true,
                delta: true,
                ..none
            },
            Bsdf::RoughPlastic(_) => BsdfFlags {
                diffuse: true,
                glossy: true,
                ..none
            },
            Bsdf::TwoSided(sides) => sides[0].flags().union(sides[1].flags()),
            Bsdf::Blend(b) => b.flags(),
            Bsdf::Mask(b) => b.flags(),
        }
    }

    /// True when the material reflects nothing, so paths can stop here.
    pub fn is_black(&self) -> bool {
        match self {
            Bsdf::Phong(b) => b.is_black(),
            Bsdf::Blend(b) => b.bsdfs.iter().all(Bsdf::is_black),
            _ => false,
        }
    }

    /// Whether `ω_o` sees a side that scatters light at all (a one-sided
    /// BSDF seen from below does not).
    pub fn scatters_towards(&self, wo: DVec3) -> bool {
        match self.side(wo) {
            (_, true) => true,
            (Bsdf::Blend(b), _) => b.scatters_towards(wo),
            (Bsdf::Mask(b), _) => b.scatters_towards(wo),
            (side, _) => side.flags().transmission || wo.z > 0.0,
        }
    }

    /// The Lambertian part `ρ(ω_o)` of the BSDF seen from `ω_o`: for every
    /// `ω_i` on `ω_o`'s side, `f(ω_o, ω_i) = ρ(ω_o)/π + r(ω_o, ω_i)`, and the
    /// irradiance cache estimates `ρ E/π` from its records while the rest
    /// `r` (possibly negative) is sampled (docs/math.md §18.3).
    ///
    /// - Phong: its diffuse albedo; `r` is the Phong lobe.
    /// - Plastic: `(1 − F(θ_o))(1 − F(0)) ρ'/η²` (the base with the
    ///   coating's transmission at normal incidence, its largest): `r =
    ///   −(1 − F(θ_o))(F(θ_i) − F(0)) ρ'/(π η²) ≤ 0` is small except at grazing `θ_i`.
    /// - Rough plastic: likewise with the rough coating's transmittance
    ///   `T(θ_o) max T`; `r` is the coating's lobe plus the base's loss
    ///   towards grazing.
    /// - Blend and mask: their components' parts, weighted as they are.
    /// - Everything else: zero.
    pub fn lambertian(&self, wo: DVec3) -> Rgb {
        match self.side(wo) {
            (side, true) => side.lambertian(flip(wo)),
            (Bsdf::Phong(b), _) if wo.z > 0.0 => b.diffuse,
            (Bsdf::Plastic(b), _) if wo.z > 0.0 => b.lambertian(wo.z),
            (Bsdf::RoughPlastic(b), _) if wo.z > 0.0 => b.lambertian(wo.z),
            (Bsdf::Blend(b), _) => b.lambertian(wo),
            (Bsdf::Mask(b), _) => b.lambertian(wo),
            _ => Rgb::BLACK,
        }
    }

    /// The Phong model behind this BSDF, which the cache integrates by
    /// BMC with its lobe as the density.
    pub fn phong(&self) -> Option<&Phong> {
        match self {
            Bsdf::Phong(b) => Some(b),
            _ => None,
        }
    }
}

/// The distribution of `r`, or `None` when the roughness is below what
/// the microfacet models resolve (the smooth model is used instead).
fn microfacet(r: &Roughness, lookup: Lookup) -> Option<Microfacet> {
    let kind = match r.distribution {
        Distribution::Beckmann => MicrofacetKind::Beckmann,
        Distribution::Ggx => MicrofacetKind::Ggx,
    };
    match (lookup, &r.textures) {
        // A roughness map's texels below the smallest roughness stay rough
        // (the material is rough wherever it is, as its mean says).
        (Lookup::At(uv), Some(_)) => {
            let (u, v) = r.at(uv);
            Microfacet::new(kind, u.max(MIN_ALPHA), v.max(MIN_ALPHA))
        }
        _ => Microfacet::new(kind, r.alpha_u, r.alpha_v),
    }
}

impl From<&Material> for Bsdf {
    /// The material's BSDF with each texture at its mean: what stands for
    /// the material where no surface point is at hand, and the template
    /// that [`Bsdf::textured`] takes its precomputed tables from.
    fn from(material: &Material) -> Self {
        build(material, Lookup::Mean, None)
    }
}

impl Bsdf {
    /// The BSDF of a textured `material` at texture coordinates `uv`;
    /// `template` is `Bsdf::from(material)`, whose precomputed tables (the
    /// plastics' coatings) are reused.
    pub fn textured(material: &Material, uv: DVec2, template: &Bsdf) -> Bsdf {
        build(material, Lookup::At(uv), Some(template))
    }
}

/// Where a material's textures are read.
#[derive(Clone, Copy)]
enum Lookup {
    /// At texture coordinates `(u, v)`.
    At(DVec2),
    /// Their means.
    Mean,
}

/// The BSDF of `material` with its textures valued by `lookup`, reusing
/// the precomputations of `template` (a BSDF of the same material).
fn build(material: &Material, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
    let rgb = |c: &[f64; 3]| Rgb::from_array(*c);
    let tex = |t: &Texture| match lookup {
        Lookup::At(uv) => Rgb::from_array(t.eval(uv)),
        Lookup::Mean => Rgb::from_array(t.mean()),
    };
    let scalar = |t: &Texture| match lookup {
        Lookup::At(uv) => t.eval_scalar(uv),
        Lookup::Mean => t.mean_scalar(),
    };
    match material {
        Material::Diffuse { reflectance } => Bsdf::Phong(Phong::lambert(tex(reflectance))),
        Material::Glossy {
            diffuse,
            specular,
            exponent,
        } => Bsdf::Phong(Phong::new(rgb(diffuse), rgb(specular), *exponent)),
        Material::Conductor {
            eta,
            k,
            specular_reflectance,
            roughness,
        } => {
            let (eta, k, specular_reflectance) = (rgb(eta), rgb(k), tex(specular_reflectance));
            match roughness.as_ref().and_then(|r| microfacet(r, lookup)) {
                Some(distribution) => Bsdf::RoughConductor(RoughConductor {
                    distribution,
                    eta,
                    k,
                    specular_reflectance,
                }),
                None => Bsdf::Conductor(Conductor {
                    eta,
                    k,
                    specular_reflectance,
                }),
            }
        }
        Material::Dielectric {
            eta,
            specular_reflectance,
            specular_transmittance,
            roughness,
            thin,
        } => {
            let (eta, specular_reflectance, specular_transmittance) =
                (*eta, tex(specular_reflectance), tex(specular_transmittance));
            match (thin, roughness.as_ref().and_then(|r| microfacet(r, lookup))) {
                (true, _) => Bsdf::ThinDielectric(ThinDielectric {
                    eta,
                    specular_reflectance,
                    specular_transmittance,
                }),
                (false, Some(distribution)) => Bsdf::RoughDielectric(RoughDielectric {
                    distribution,
                    eta,
                    specular_reflectance,
                    specular_transmittance,
                }),
                (false, None) => Bsdf::Dielectric(Dielectric {
                    eta,
                    specular_reflectance,
                    specular_transmittance,
                }),
            }
        }
        Material::Plastic {
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
            roughness,
        } => {
            let (diffuse, specular) = (tex(diffuse_reflectance), tex(specular_reflectance));
            match (
                roughness.as_ref().and_then(|r| microfacet(r, Lookup::Mean)),
                template,
            ) {
                (Some(_), Some(Bsdf::RoughPlastic(t))) => {
                    Bsdf::RoughPlastic(t.retinted(diffuse, specular, *nonlinear))
                }
                (Some(distribution), _) => Bsdf::RoughPlastic(RoughPlastic::new(
                    distribution,
                    diffuse,
                    specular,
                    *eta,
                    *nonlinear,
                )),
                (None, Some(Bsdf::Plastic(t))) => {
                    Bsdf::Plastic(t.retinted(diffuse, specular, *nonlinear))
                }
                (None, _) => Bsdf::Plastic(Plastic::new(diffuse, specular, *eta, *nonlinear)),
            }
        }
        Material::TwoSided { front, back } => {
            let sides = match template {
                Some(Bsdf::TwoSided(sides)) => [Some(&sides[0]), Some(&sides[1])],
                _ => [None, None],
            };
            Bsdf::TwoSided(Box::new([
                build(front, lookup, sides[0]),
                build(back, lookup, sides[1]),
            ]))
        }
        Material::Blend { weight, bsdfs } => {
            let parts = match template {
                Some(Bsdf::Blend(b)) => [Some(&b.bsdfs[0]), Some(&b.bsdfs[1])],
                _ => [None, None],
            };
            Bsdf::Blend(Box::new(Blend {
                weight: scalar(weight).clamp(0.0, 1.0),
                bsdfs: [
                    build(&bsdfs[0], lookup, parts[0]),
                    build(&bsdfs[1], lookup, parts[1]),
                ],
            }))
        }
        Material::Mask { opacity, bsdf } => {
            let inner = match template {
                Some(Bsdf::Mask(m)) => Some(&m.bsdf),
                _ => None,
            };
            Bsdf::Mask(Box::new(Mask {
                opacity: scalar(opacity).clamp(0.0, 1.0),
                bsdf: build(bsdf, lookup, inner),
            }))
        }
    }
}

#[cfg(test)]
mod tests;
