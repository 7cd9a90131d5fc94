//! Microfacet normal distributions for rough conductors, dielectrics and
//! plastics: GGX (Trowbridge–Reitz) and Beckmann, isotropic or anisotropic
//! (`alpha_u` along the local x axis, `alpha_v` along y), with Smith's
//! masking (Walter et al. 2007, "Microfacet models for refraction through
//! rough surfaces"; Heitz 2014, "Understanding the masking-shadowing
//! function in microfacet-based BRDFs").
//!
//! Directions and normals are unit vectors in the **local frame** (z = the
//! macro-surface normal). With `m` a microfacet normal:
//! - `D(m)` is normalised so that `∫ D(m) cos θ_m dm = 1` over the upper
//!   hemisphere (the projected microfacet area equals the macro area);
//! - `G1(ω, m)` is Smith's masking `1 / (1 + Λ(ω))` where `ω·m > 0` and
//!   `ω_z > 0`, with the exact `Λ` of each distribution (Mitsuba's Beckmann
//!   uses Walter et al.'s rational fit instead, within 0.4 % of it);
//! - the distribution of visible normals seen from `ω` is
//!   `D_ω(m) = G1(ω, m) max(0, ω·m) D(m) / ω_z`, itself normalised (Heitz
//!   2014, eq. 38).
//!
//! Sampling: both distributions sample their visible normals `D_ω(m)`
//! exactly, the best strategy for a specular microfacet BSDF since no
//! sample falls on a facet the viewer cannot see (as Mitsuba 3 does by
//! default): GGX by Heitz 2018 ("Sampling the GGX distribution of visible
//! normals"), Beckmann by the slopes of Heitz & d'Eon 2014 ("Importance
//! sampling microfacet-based BSDFs using the distribution of visible
//! normals", §4 and appendix), the visible slope along the view inverted
//! from its CDF and the one across it Gaussian. Beckmann used to sample
//! `D(m) cos θ_m` (Walter et al. 2007, eqs. 28–29): on rough Beckmann
//! copper and glass seen at grazing angles its weights `f cos θ / p` spread
//! far more (docs/math.md §18.1).

use std::f64::consts::{FRAC_1_PI, PI, TAU};

use glam::DVec3;

use crate::stats::{inverse_erf, solve_increasing};

/// The shape of the microfacet normal distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    /// Trowbridge–Reitz (GGX): long tails, the default of Mitsuba's rough BSDFs.
    Ggx,
    /// Beckmann: a Gaussian distribution of slopes.
    Beckmann,
}

/// Smallest roughness accepted: below it the lobe is numerically a mirror
/// and `D` overflows; rough BSDFs treat such surfaces as smooth instead.
pub const MIN_ALPHA: f64 = 1e-4;

/// A microfacet distribution with roughnesses `alpha_u` (x) and `alpha_v`
/// (y), each in `[MIN_ALPHA, ∞)` (checked by [`Microfacet::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    kind: MicrofacetKind,
    alpha_u: f64,
    alpha_v: f64,
}

/// A sampled microfacet normal and the density it was drawn with
/// (solid angle of `m`, sr⁻¹; see [`Microfacet::pdf`]).
#[derive(Clone, Copy, Debug)]
pub struct NormalSample {
    pub m: DVec3,
    pub pdf: f64,
}

impl Microfacet {
    /// The distribution, or `None` if a roughness is not finite or is below
    /// [`MIN_ALPHA`].
    pub fn new(kind: MicrofacetKind, alpha_u: f64, alpha_v: f64) -> Option<Self> {
        let valid = |a: f64| a.is_finite() && a >= MIN_ALPHA;
        (valid(alpha_u) && valid(alpha_v)).then_some(Self {
            kind,
            alpha_u,
            alpha_v,
        })
    }

    pub fn kind(&self) -> MicrofacetKind {
        self.kind
    }

    /// `(alpha_u, alpha_v)`.
    pub fn alpha(&self) -> (f64, f64) {
        (self.alpha_u, self.alpha_v)
    }

    /// `D(m)`, sr⁻¹; zero for normals at or below the horizon.
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = (self.alpha_u, self.alpha_v);
        let cos2 = m.z * m.z;
        // tan²θ_m split by azimuth: (m_x²/α_u² + m_y²/α_v²) / cos²θ_m.
        let slope2 = (m.x * m.x / (ax * ax) + m.y * m.y / (ay * ay)) / cos2;
        match self.kind {
            MicrofacetKind::Ggx => {
                let t = 1.0 + slope2;
                FRAC_1_PI / (ax * ay * cos2 * cos2 * t * t)
            }
            MicrofacetKind::Beckmann => (-slope2).exp() * FRAC_1_PI / (ax * ay * cos2 * cos2),
        }
    }

    /// Smith's `Λ(ω)` for a direction above the surface (Heitz 2014,
    /// eqs. 72 and 86), zero at the normal.
    pub fn lambda(&self, w: DVec3) -> f64 {
        let (ax, ay) = (self.alpha_u, self.alpha_v);
        // α(ω)² tan²θ = (α_u² ω_x² + α_v² ω_y²) / ω_z².
        let a2t2 = (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / (w.z * w.z);
        // At the normal (and for a NaN from ω_z = 0) nothing is masked.
        if a2t2.is_nan() || a2t2 <= 0.0 {
            return 0.0;
        }
        match self.kind {
            MicrofacetKind::Ggx => 0.5 * ((1.0 + a2t2).sqrt() - 1.0),
            MicrofacetKind::Beckmann => {
                // Λ = (erf(a) − 1)/2 + e^(−a²)/(2a√π), a = 1/(α tan θ), with
                // erf(a) − 1 = −erfc(a) to keep precision at grazing-free angles.
                let a = 1.0 / a2t2.sqrt();
                0.5 * ((-a * a).exp() / (a * PI.sqrt()) - libm::erfc(a))
            }
        }
    }

    /// Smith's masking of `m` seen from `w`: `1 / (1 + Λ(w))` where `w`
    /// sees the facet's front (`w·m > 0`) from above the surface, else 0.
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.z <= 0.0 || w.dot(m) <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// Separable masking-shadowing of `m` between `wi` and `wo` (module
    /// docs), both above the surface and on `m`'s front.
    pub fn g(&self, wi: DVec3, wo: DVec3, m: DVec3) -> f64 {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// Density of the normal [`Self::sample`] draws for a viewer at `w`
    /// (`w_z > 0`), sr⁻¹: the visible normals' `D_w(m)` (module docs).
    pub fn pdf(&self, w: DVec3, m: DVec3) -> f64 {
        if w.z <= 0.0 {
            return 0.0;
        }
        self.g1(w, m) * w.dot(m).max(0.0) * self.d(m) / w.z
    }

    /// A microfacet normal for a viewer at `w` (`w_z > 0`) from two uniform
    /// numbers in `[0, 1)`.
    pub fn sample(&self, w: DVec3, u: [f64; 2]) -> NormalSample {
        let m = match self.kind {
            MicrofacetKind::Ggx => self.sample_ggx_visible(w, u),
            MicrofacetKind::Beckmann => self.sample_beckmann_visible(w, u),
        };
        NormalSample {
            m,
            pdf: self.pdf(w, m),
        }
    }

    /// Heitz 2018: stretch the view to the unit-roughness configuration,
    /// sample the projected hemisphere seen from it, unstretch the normal.
    fn sample_ggx_visible(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        let (ax, ay) = (self.alpha_u, self.alpha_v);
        let vh = DVec3::new(ax * w.x, ay * w.y, w.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            DVec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            DVec3::X
        };
        let t2 = vh.cross(t1);
        let r = u[0].sqrt();
        let phi = TAU * u[1];
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        DVec3::new(ax * nh.x, ay * nh.y, nh.z.max(1e-12)).normalize()
    }

    /// Heitz & d'Eon 2014: stretch the view to unit roughness, draw the
    /// visible slopes there (the one along the view's azimuth from its CDF,
    /// the one across it from the Gaussian it is), rotate them back to the
    /// view's azimuth and unstretch them.
    fn sample_beckmann_visible(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        let (ax, ay) = (self.alpha_u, self.alpha_v);
        let v = DVec3::new(ax * w.x, ay * w.y, w.z).normalize();
        let sin_theta = (v.x * v.x + v.y * v.y).sqrt();
        // Slopes of the unit Beckmann distribution are independent normals
        // of variance ½; seen at an angle, the one along the view is skewed.
        let across = inverse_erf(2.0 * u[1] - 1.0);
        let (along, cos_phi, sin_phi) = if sin_theta < 1e-12 {
            (inverse_erf(2.0 * u[0] - 1.0), 1.0, 0.0)
        } else {
            (
                beckmann_visible_slope(v.z / sin_theta, u[0]),
                v.x / sin_theta,
                v.y / sin_theta,
            )
        };
        let sx = ax * (cos_phi * along - sin_phi * across);
        let sy = ay * (sin_phi * along + cos_phi * across);
        DVec3::new(-sx, -sy, 1.0).normalize()
    }
}

/// The slope `x` along the view of a visible normal of the unit Beckmann
/// distribution seen at `cot θ = mu` (≥ 0), for `u ∈ [0, 1)`: the
/// density of `x` is `∝ (mu − x) e^(−x²)` for `x < mu` (the projected
/// area of the facet towards the view, Heitz & d'Eon 2014, eq. 13), its
/// integral from −∞ `A(x) = mu (√π/2) erfc(−x) + e^(−x²)/2`; `A(x) = u A(mu)`
/// is solved by [`solve_increasing`].
fn beckmann_visible_slope(mu: f64, u: f64) -> f64 {
    let half_sqrt_pi = 0.5 * PI.sqrt();
    let a = |x: f64| mu * half_sqrt_pi * libm::erfc(-x) + 0.5 * (-x * x).exp();
    let total = a(mu);
    // Below −6 the mass left is under 1e-16 of any total.
    solve_increasing(
        a,
        |x| (mu - x) * (-x * x).exp(),
        u * total,
        (-6.0, mu),
        (mu - 1.0).clamp(-6.0, 0.0),
        1e-15 * total,
    )
}

#[cfg(test)]
mod tests;
