//! Warps from the unit square `[0,1)²` to directions, with their densities
//! (solid-angle measure, sr⁻¹). Directions are in the local frame (z = normal)
//! unless a function says otherwise.
//!
//! Source: Pharr, Jakob & Humphreys, *Physically Based Rendering* 4th ed.,
//! §A.5 (sampling the hemisphere and sphere).

use std::f64::consts::{FRAC_1_PI, PI, TAU};

use glam::DVec3;

/// Cosine-weighted direction on the upper hemisphere, density `cos θ / π`.
///
/// Malley's method: a uniform point on the unit disk projected up. Uses the
/// polar map rather than the concentric one; both have the same density.
pub fn cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let r = u[0].sqrt();
    let phi = TAU * u[1];
    let z = (1.0 - u[0]).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`cosine_hemisphere`] at local direction `w`.
pub fn cosine_hemisphere_pdf(w: DVec3) -> f64 {
    w.z.max(0.0) * FRAC_1_PI
}

/// Uniform direction on the whole sphere, density `1 / (4π)`.
pub fn uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u[1];
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_sphere`].
pub const UNIFORM_SPHERE_PDF: f64 = 1.0 / (4.0 * PI);

/// Direction at angle `α` from the z axis with `cos α = u₀^{1/(m+1)}`:
/// density `(m+1)/(2π) cos^m α` about z (the sampling density of the modified
/// Phong lobe; Lafortune & Willems 1994).
pub fn power_cosine(u: [f64; 2], exponent: f64) -> DVec3 {
    let cos = u[0].powf(1.0 / (exponent + 1.0));
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = TAU * u[1];
    DVec3::new(sin * phi.cos(), sin * phi.sin(), cos)
}

/// Density of [`power_cosine`] for a direction with `cos α = cos_alpha`.
pub fn power_cosine_pdf(cos_alpha: f64, exponent: f64) -> f64 {
    if cos_alpha <= 0.0 {
        0.0
    } else {
        (exponent + 1.0) / TAU * cos_alpha.powf(exponent)
    }
}

/// Test quadrature: midpoint rule over `(z, φ)` for `z ∈ [z_min, 1]`, using
/// `dω = dz dφ` about the z axis (`z_min = -1`: sphere, `0`: hemisphere).
#[cfg(test)]
pub(crate) fn integrate_directions(
    f: impl Fn(DVec3) -> f64,
    z_min: f64,
    nz: usize,
    nphi: usize,
) -> f64 {
    let dz = (1.0 - z_min) / nz as f64;
    let dphi = TAU / nphi as f64;
    let mut sum = 0.0;
    for i in 0..nz {
        let z = z_min + (i as f64 + 0.5) * dz;
        let r = (1.0 - z * z).max(0.0).sqrt();
        for j in 0..nphi {
            let phi = (j as f64 + 0.5) * dphi;
            sum += f(DVec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    sum * dz * dphi
}

#[cfg(test)]
mod tests {
    use super::*;

    fn integrate_sphere(f: impl Fn(DVec3) -> f64) -> f64 {
        integrate_directions(f, -1.0, 800, 64)
    }

    #[test]
    fn densities_integrate_to_one() {
        assert!((integrate_sphere(cosine_hemisphere_pdf) - 1.0).abs() < 1e-4);
        assert!((integrate_sphere(|_| UNIFORM_SPHERE_PDF) - 1.0).abs() < 1e-10);
        for m in [0.0, 1.0, 10.0, 50.0] {
            let total = integrate_sphere(|w| power_cosine_pdf(w.z, m));
            assert!((total - 1.0).abs() < 2e-3, "m = {m}: {total}");
        }
    }

    #[test]
    fn warps_give_unit_vectors_with_the_stated_density() {
        // The fraction of samples with z > 0.5 must equal the density's mass there.
        let n = 64;
        let mut hits = [0usize; 3];
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                let dirs = [
                    cosine_hemisphere(u),
                    uniform_sphere(u),
                    power_cosine(u, 5.0),
                ];
                for (k, w) in dirs.iter().enumerate() {
                    assert!((w.length() - 1.0).abs() < 1e-12);
                    hits[k] += usize::from(w.z > 0.5);
                }
            }
        }
        let frac = hits.map(|h| h as f64 / (n * n) as f64);
        // cosine: 1 - 0.5², uniform: 0.25, power cosine m=5: 1 - 0.5⁶.
        assert!((frac[0] - 0.75).abs() < 0.01, "{frac:?}");
        assert!((frac[1] - 0.25).abs() < 0.01, "{frac:?}");
        assert!((frac[2] - (1.0 - 0.5f64.powi(6))).abs() < 0.01, "{frac:?}");
    }
}
