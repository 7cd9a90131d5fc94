//! Synthetic lighting environments with accurately known irradiance.
//!
//! They are the ground truth of the estimator convergence study. Every environment is a radiance field `L(ω)` over the whole
//! sphere in the **local frame** (z = surface normal, W/(m²·sr)) together with
//! its irradiance `E = ∫_H L(ω) cos θ dω` (W/m², docs/math.md §1), computed by
//! deterministic high-order quadrature that the tests check against closed
//! forms. Two families:
//! - [`SphericalGaussianEnvironment`]: a constant term plus spherical-Gaussian
//!   lobes (docs/math.md §4), smooth everywhere; lobes may straddle the horizon.
//! - [`CapEnvironment`]: a constant term plus a uniformly bright spherical cap
//!   ("disk light"), whose edge and horizon clipping make `L` discontinuous.

use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::num::NonZeroUsize;

use gauss_quad::legendre::GaussLegendre;

/// A radiance field with known irradiance, both in the local frame.
pub trait Environment: Send + Sync {
    /// Incident radiance from the local direction `direction` (unit vector).
    fn radiance(&self, direction: DVec3) -> f64;
    /// Irradiance `E = ∫_H L cos θ dω` at the shading point (W/m²).
    fn irradiance(&self) -> f64;
}

/// Which synthetic family an environment belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnvironmentFamily {
    /// Constant plus spherical-Gaussian lobes ([`SphericalGaussianEnvironment`]).
    Smooth,
    /// Constant plus a hemisphere-clipped disk light ([`CapEnvironment`]).
    Sharp,
}

impl EnvironmentFamily {
    /// The `index`-th environment of this family for `seed`, deterministic.
    pub fn environment(self, seed: u64, index: u64) -> Box<dyn Environment> {
        // Mixing the index into the seed keeps environments independent of
        // how many others were drawn before them.
        let mut rng = Pcg64::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        match self {
            Self::Smooth => Box::new(SphericalGaussianEnvironment::random(&mut rng)),
            Self::Sharp => Box::new(CapEnvironment::random(&mut rng)),
        }
    }
}

/// One spherical Gaussian `a e^{λ(μ·ω − 1)}` (docs/math.md §4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SgLobe {
    /// Unit axis `μ` in the local frame.
    pub axis: DVec3,
    /// Sharpness `λ > 0` (1/sr-ish; the lobe's angular width is ~`1/√λ` rad).
    pub sharpness: f64,
    /// Peak radiance `a` (W/(m²·sr)).
    pub amplitude: f64,
}

impl SgLobe {
    fn eval(&self, direction: DVec3) -> f64 {
        self.amplitude * (self.sharpness * (self.axis.dot(direction) - 1.0)).exp()
    }

    /// `∫_H a e^{λ(μ·ω−1)} cos θ dω` by a product rule: Gauss–Legendre panels
    /// in θ and the periodic trapezoid rule in φ. The φ-integrand is the
    /// analytic periodic function `e^{λ sin θ_μ sin θ cos φ}`, for which the
    /// M-point trapezoid rule errs by ~`I_M(x)/I_0(x)` (x ≤ λ): negligible for
    /// M = 256 and the sharpnesses used here (λ ≤ 50).
    fn hemisphere_cosine_integral(&self) -> f64 {
        const AZIMUTHS: usize = 256;
        let cos_axis = self.axis.z;
        let sin_axis = (1.0 - cos_axis * cos_axis).max(0.0).sqrt();
        let azimuth_cosines: Vec<f64> = (0..AZIMUTHS)
            .map(|j| (TAU * j as f64 / AZIMUTHS as f64).cos())
            .collect();
        let per_theta = |theta: f64| {
            let (sin_t, cos_t) = theta.sin_cos();
            let ring: f64 = azimuth_cosines
                .iter()
                .map(|c| {
                    // μ·ω − 1 ≤ 0, so the exponent never overflows.
                    (self.sharpness * (cos_axis * cos_t + sin_axis * sin_t * c - 1.0)).exp()
                })
                .sum::<f64>()
                * (TAU / AZIMUTHS as f64);
            ring * cos_t * sin_t
        };
        self.amplitude * panels(0.0, FRAC_PI_2, 16, per_theta)
    }
}

/// `∫_a^b f` with `count` equal Gauss–Legendre panels of 24 nodes each.
fn panels(a: f64, b: f64, count: usize, mut f: impl FnMut(f64) -> f64) -> f64 {
    let rule = GaussLegendre::new(NonZeroUsize::new(24).expect("24 is non-zero"));
    let width = (b - a) / count as f64;
    (0..count)
        .map(|k| {
            let lo = a + width * k as f64;
            rule.integrate(lo, lo + width, &mut f)
        })
        .sum()
}

/// Constant radiance plus spherical-Gaussian lobes: the smooth family.
#[derive(Clone, Debug, PartialEq)]
pub struct SphericalGaussianEnvironment {
    /// Radiance of the constant term (W/(m²·sr)).
    pub constant: f64,
    /// The lobes; axes may point below the horizon.
    pub lobes: Vec<SgLobe>,
    irradiance: f64,
}

impl SphericalGaussianEnvironment {
    /// Environment with the given terms; its irradiance is integrated here.
    /// Irradiance of the constant is `π·constant` exactly (docs/math.md §8).
    pub fn new(constant: f64, lobes: Vec<SgLobe>) -> Self {
        let irradiance = PI * constant
            + lobes
                .iter()
                .map(SgLobe::hemisphere_cosine_integral)
                .sum::<f64>();
        Self {
            constant,
            lobes,
            irradiance,
        }
    }

    /// A random member of the family: constant in [0.1, 0.5], one to four
    /// lobes with amplitude in [0.5, 2], sharpness log-uniform in [1, 10]
    /// (angular widths ~0.3–1 rad) and axes uniform over `z ∈ [−0.3, 1]`, so
    /// some lobes straddle the horizon.
    pub fn random(rng: &mut Pcg64) -> Self {
        let constant = rng.random_range(0.1..0.5);
        let count = rng.random_range(1..=4);
        let lobes = (0..count)
            .map(|_| SgLobe {
                axis: random_axis(rng, -0.3),
                sharpness: 10f64.powf(rng.random::<f64>()),
                amplitude: rng.random_range(0.5..2.0),
            })
            .collect();
        Self::new(constant, lobes)
    }
}

impl Environment for SphericalGaussianEnvironment {
    fn radiance(&self, direction: DVec3) -> f64 {
        self.constant + self.lobes.iter().map(|l| l.eval(direction)).sum::<f64>()
    }

    fn irradiance(&self) -> f64 {
        self.irradiance
    }
}

/// Unit vector uniform over the zone `z ∈ [min_z, 1]` of the sphere.
fn random_axis(rng: &mut Pcg64, min_z: f64) -> DVec3 {
    let z: f64 = rng.random_range(min_z..1.0);
    let phi = rng.random_range(0.0..TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Constant radiance plus a spherical cap of uniform extra radiance: the
/// sharp family (a distant disk light, clipped by the horizon).
#[derive(Clone, Debug, PartialEq)]
pub struct CapEnvironment {
    /// Radiance of the constant term (W/(m²·sr)).
    pub background: f64,
    /// Unit direction of the cap's centre (local frame).
    pub centre: DVec3,
    /// Angular radius `α` of the cap (rad, in (0, π/2)).
    pub half_angle: f64,
    /// Radiance added inside the cap (W/(m²·sr)).
    pub radiance: f64,
    irradiance: f64,
}

impl CapEnvironment {
    /// Environment with the given terms; its irradiance is integrated here.
    pub fn new(background: f64, centre: DVec3, half_angle: f64, radiance: f64) -> Self {
        let irradiance = PI * background + radiance * cap_cosine_integral(centre.z, half_angle);
        Self {
            background,
            centre,
            half_angle,
            radiance,
            irradiance,
        }
    }

    /// A random member: background in [0.1, 0.5], half-angle in [0.15, 0.5]
    /// rad, cap radiance in [2, 10], centre uniform over `z ∈ [−0.2, 1]`
    /// (so many caps are cut by the horizon, some are below it).
    pub fn random(rng: &mut Pcg64) -> Self {
        let background = rng.random_range(0.1..0.5);
        let half_angle = rng.random_range(0.15..0.5);
        let radiance = rng.random_range(2.0..10.0);
        let centre = random_axis(rng, -0.2);
        Self::new(background, centre, half_angle, radiance)
    }
}

impl Environment for CapEnvironment {
    fn radiance(&self, direction: DVec3) -> f64 {
        let inside = direction.dot(self.centre) >= self.half_angle.cos();
        self.background + if inside { self.radiance } else { 0.0 }
    }

    fn irradiance(&self) -> f64 {
        self.irradiance
    }
}

/// `∫_H 1[ω in cap] cos θ dω` for a cap of angular radius `α` whose centre has
/// `cos θ_c = cos_centre`.
///
/// Integrates the azimuthal extent of the cap ring by ring: at polar angle θ
/// the cap covers the azimuths `|φ − φ_c| ≤ Δφ(θ)` with
/// `cos Δφ = (cos α − cos θ cos θ_c)/(sin θ sin θ_c)` (spherical law of
/// cosines). Where the cap contains the whole ring (θ < α − θ_c) the integral
/// is `π sin²(α − θ_c)` in closed form. Elsewhere `Δφ` has square-root
/// behaviour at the ring limits, which the substitution θ = a + (b − a)sin²t
/// removes, so Gauss–Legendre converges exponentially.
fn cap_cosine_integral(cos_centre: f64, half_angle: f64) -> f64 {
    let theta_c = cos_centre.clamp(-1.0, 1.0).acos();
    let (sin_c, cos_c) = theta_c.sin_cos();
    let cos_alpha = half_angle.cos();
    let full_ring_end = (half_angle - theta_c).clamp(0.0, FRAC_PI_2);
    let full = PI * full_ring_end.sin().powi(2);
    let lo = (theta_c - half_angle).abs().min(FRAC_PI_2);
    let hi = (theta_c + half_angle).min(FRAC_PI_2);
    if hi <= lo {
        return full;
    }
    let extent = |theta: f64| {
        let (sin_t, cos_t) = theta.sin_cos();
        let denom = sin_t * sin_c;
        let cos_delta = if denom > 0.0 {
            ((cos_alpha - cos_t * cos_c) / denom).clamp(-1.0, 1.0)
        } else {
            1.0
        };
        2.0 * cos_delta.acos() * cos_t * sin_t
    };
    let partial = panels(0.0, FRAC_PI_2, 2, |t| {
        let s = t.sin();
        let theta = lo + (hi - lo) * s * s;
        extent(theta) * (hi - lo) * 2.0 * s * t.cos()
    });
    full + partial
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polar(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// ∫_{S²} e^{λ(μ·ω−1)} (n·ω) dω = 2π μ_z e^{−λ} ∫_{−1}^{1} t e^{λt} dt.
    fn sg_full_sphere_cosine(lambda: f64, axis_z: f64) -> f64 {
        let antiderivative = |t: f64| (t / lambda - 1.0 / (lambda * lambda)) * (lambda * t).exp();
        TAU * axis_z * (-lambda).exp() * (antiderivative(1.0) - antiderivative(-1.0))
    }

    #[test]
    fn constant_environment_is_the_furnace() {
        let env = SphericalGaussianEnvironment::new(0.7, Vec::new());
        assert!((env.irradiance() - 0.7 * PI).abs() < 1e-15);
    }

    #[test]
    fn zenith_lobe_matches_closed_form() {
        for lambda in [0.5, 2.0, 10.0, 40.0] {
            let lobe = SgLobe {
                axis: DVec3::Z,
                sharpness: lambda,
                amplitude: 1.3,
            };
            // 2π ∫₀¹ e^{λ(u−1)} u du = 2π (1/λ − 1/λ² + e^{−λ}/λ²).
            let exact = 1.3 * TAU * (1.0 / lambda - (1.0 - (-lambda).exp()) / (lambda * lambda));
            let got = lobe.hemisphere_cosine_integral();
            assert!(
                (got - exact).abs() < 1e-13 * exact,
                "λ={lambda}: {got} vs {exact}"
            );
        }
    }

    #[test]
    fn straddling_lobes_match_full_sphere_closed_form() {
        // Reflecting the axis through the horizon plane maps the lower half of
        // ∫_{S²} G cos θ onto the upper one with the sign of cos θ flipped.
        for (lambda, theta) in [(1.0, 1.2), (5.0, 1.5), (20.0, 1.62), (3.0, 0.4)] {
            let lobe = SgLobe {
                axis: polar(theta, 0.7),
                sharpness: lambda,
                amplitude: 1.0,
            };
            let mirrored = SgLobe {
                axis: lobe.axis * DVec3::new(1.0, 1.0, -1.0),
                ..lobe
            };
            let got = lobe.hemisphere_cosine_integral() - mirrored.hemisphere_cosine_integral();
            let exact = sg_full_sphere_cosine(lambda, lobe.axis.z);
            assert!(
                (got - exact).abs() < 1e-12,
                "λ={lambda} θ={theta}: {got} vs {exact}"
            );
        }
    }

    #[test]
    fn caps_above_the_horizon_match_closed_form() {
        // A cap entirely above the horizon: E = π sin²α cos θ_c.
        for (theta_c, alpha) in [(0.0, 0.3), (0.2, 0.5), (0.9, 0.4), (1.1, 0.45)] {
            let got = cap_cosine_integral(f64::cos(theta_c), alpha);
            let exact = PI * alpha.sin().powi(2) * f64::cos(theta_c);
            assert!(
                (got - exact).abs() < 1e-12 * exact,
                "{theta_c} {alpha}: {got} vs {exact}"
            );
        }
    }

    #[test]
    fn clipped_caps_match_full_sphere_closed_form() {
        // ∫_{S²} 1[cap] cos θ dω = π sin²α cos θ_c for any cap; the reflected
        // cap supplies the part below the horizon.
        for (theta_c, alpha) in [(1.4, 0.4), (1.56, 0.3), (1.7, 0.5), (1.3, 0.45)] {
            let upper = cap_cosine_integral(f64::cos(theta_c), alpha);
            let lower = cap_cosine_integral(-f64::cos(theta_c), alpha);
            let exact = PI * alpha.sin().powi(2) * f64::cos(theta_c);
            assert!((upper - lower - exact).abs() < 1e-12, "{theta_c} {alpha}");
            assert!(upper > 0.0 && upper > exact);
        }
    }

    #[test]
    fn integrals_agree_with_brute_force_grid() {
        // Independent check: midpoint rule in (cos θ, φ) on a fine grid.
        let grid = |env: &dyn Environment| {
            let n = 1500;
            let mut sum = 0.0;
            for i in 0..n {
                let u = (i as f64 + 0.5) / n as f64;
                let s = (1.0 - u * u).sqrt();
                for j in 0..n {
                    let phi = TAU * (j as f64 + 0.5) / n as f64;
                    sum += env.radiance(DVec3::new(s * phi.cos(), s * phi.sin(), u)) * u;
                }
            }
            sum * TAU / (n * n) as f64
        };
        for family in [EnvironmentFamily::Smooth, EnvironmentFamily::Sharp] {
            for index in 0..2 {
                let env = family.environment(7, index);
                let reference = grid(env.as_ref());
                let tolerance = match family {
                    EnvironmentFamily::Smooth => 1e-5,
                    EnvironmentFamily::Sharp => 2e-3,
                };
                let rel = (env.irradiance() - reference).abs() / reference;
                assert!(rel < tolerance, "{family:?} {index}: rel {rel}");
            }
        }
    }

    #[test]
    fn families_are_deterministic_and_varied() {
        let a = EnvironmentFamily::Smooth.environment(3, 1).irradiance();
        let b = EnvironmentFamily::Smooth.environment(3, 1).irradiance();
        let c = EnvironmentFamily::Smooth.environment(3, 2).irradiance();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }
}
