//! Kernel means `z(ω) = ∫_H k(ω, ω') p(ω') dω'` and the prior variance
//! `V₀ = ∫∫ k(ω, ω') p(ω) p(ω') dω dω'` (docs/math.md §3–4).
//!
//! [`KernelMeanMethod::Exact`] integrates by deterministic adaptive quadrature
//! (see [`exact`]) to ~1e-12 relative; [`KernelMeanMethod::SphericalGaussian`]
//! uses the closed-form SG approximation of Marques et al. 2013 (SE kernel
//! only), whose measured error is documented in `docs/BENCHMARKS.md`.

mod exact;
mod spherical_gaussian;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::density::Density;
use super::error::BmcError;
use super::kernel::Kernel;

/// How kernel means and `V₀` are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelMeanMethod {
    /// Deterministic adaptive quadrature, ~1e-12 relative (see `exact`).
    #[default]
    Exact,
    /// Spherical-Gaussian closed form (Marques et al. 2013): SE kernel only,
    /// approximate (errors in `docs/BENCHMARKS.md`).
    SphericalGaussian,
}

/// Kernel means at each direction (local frame), in order.
pub fn kernel_means(
    directions: &[DVec3],
    kernel: &Kernel,
    density: &Density,
    method: KernelMeanMethod,
) -> Result<Vec<f64>, BmcError> {
    kernel.validate()?;
    density.validate()?;
    match method {
        KernelMeanMethod::Exact => Ok(exact::kernel_means(directions, kernel, density)),
        KernelMeanMethod::SphericalGaussian => {
            spherical_gaussian::kernel_means(directions, kernel, density)
        }
    }
}

/// Prior variance `V₀` of the integral (units of `f`² · (∫p)²).
pub fn prior_variance(
    kernel: &Kernel,
    density: &Density,
    method: KernelMeanMethod,
) -> Result<f64, BmcError> {
    kernel.validate()?;
    density.validate()?;
    match method {
        KernelMeanMethod::Exact => Ok(exact::prior_variance(kernel, density)),
        KernelMeanMethod::SphericalGaussian => spherical_gaussian::prior_variance(kernel, density),
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{FRAC_PI_2, TAU};

    use glam::DVec3;

    use super::*;
    use crate::bmc::integrate::GaussLegendre;
    use crate::bmc::kernel::KernelKind;

    /// Brute-force `z(ω_i)` in the local frame, independent of the reductions
    /// used by the exact method: composite Gauss–Legendre in `μ = cos θ`
    /// (panels split at `μ_i` and at `extra` breaks) times the periodic
    /// trapezoid rule in `φ` with a node on the azimuth of `ω_i`.
    fn brute_force_mean(
        w: DVec3,
        kernel: &Kernel,
        density: &Density,
        extra: &[f64],
        panels: usize,
        n_phi: usize,
    ) -> f64 {
        let rule = GaussLegendre::new(20);
        let mut points: Vec<f64> = (0..=panels).map(|i| i as f64 / panels as f64).collect();
        points.push(w.z);
        points.extend_from_slice(extra);
        points.retain(|x| (0.0..=1.0).contains(x));
        points.sort_by(f64::total_cmp);
        points.dedup();
        let phi_i = w.y.atan2(w.x);
        let mut total = 0.0;
        for p in points.windows(2) {
            total += rule.integrate(
                &|mu: f64| {
                    let s = (1.0 - mu * mu).max(0.0).sqrt();
                    let mut sum = 0.0;
                    for j in 0..n_phi {
                        let phi = phi_i + TAU * j as f64 / n_phi as f64;
                        let v = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
                        sum += kernel.eval(w, v) * density.eval(v);
                    }
                    sum * TAU / n_phi as f64
                },
                p[0],
                p[1],
            );
        }
        total
    }

    /// Asserts that the exact mean at `w` is within `rel_tol` of the brute force.
    fn assert_matches_brute_force(
        w: DVec3,
        kernel: &Kernel,
        density: &Density,
        extra: &[f64],
        n_phi: usize,
        rel_tol: f64,
    ) {
        let exact = kernel_means(&[w], kernel, density, KernelMeanMethod::Exact).unwrap()[0];
        let brute = brute_force_mean(w, kernel, density, extra, 40, n_phi);
        let rel = (exact / brute - 1.0).abs();
        assert!(rel < rel_tol, "{kernel:?} {density:?} ω={w}: {rel:e}");
    }

    fn direction(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// SE + Lambert (and uniform) by the 1-D Bessel formula within
    /// 1e-10 relative of brute-force 2-D quadrature for ℓ ∈ [0.1, 3].
    #[test]
    fn bessel_formula_matches_brute_force_2d() {
        for ell in [0.1, 0.3, 1.0, 3.0] {
            let k = Kernel::new(KernelKind::SquaredExponential, ell, 1.7, 0.0).unwrap();
            for density in [Density::Lambert, Density::Uniform] {
                for theta in [0.0, 0.4, 1.1, 1.5, FRAC_PI_2] {
                    let w = direction(theta, 0.7);
                    assert_matches_brute_force(w, &k, &density, &[], 512, 1e-10);
                }
            }
        }
    }

    /// Matérn kernels (frame about ω_i) against the same brute force; the
    /// kernel's kink at ω_i limits the brute force, not the exact method.
    #[test]
    fn matern_means_match_brute_force_2d() {
        for kind in [KernelKind::Matern32, KernelKind::Matern52] {
            for ell in [0.2, 1.0] {
                let k = Kernel::new(kind, ell, 1.0, 0.0).unwrap();
                for density in [Density::Lambert, Density::Uniform] {
                    // Not at the pole: there the kink at ω_i becomes a
                    // (1 − μ)^{3/2} endpoint singularity for the brute force.
                    for theta in [0.3, 0.8, 1.45] {
                        let w = direction(theta, -2.0);
                        assert_matches_brute_force(w, &k, &density, &[], 1024, 1e-9);
                    }
                }
            }
        }
    }

    /// The two exact reductions (Bessel in the normal frame, 1-D in the frame
    /// about ω_i) agree for the SE kernel.
    #[test]
    fn both_exact_reductions_agree_for_the_se_kernel() {
        for ell in [0.05, 0.2, 1.0, 3.0] {
            let k = Kernel::new(KernelKind::SquaredExponential, ell, 1.0, 0.0).unwrap();
            for density in [Density::Lambert, Density::Uniform] {
                for theta in [0.0, 0.3, 0.9, 1.3, FRAC_PI_2, 2.0] {
                    let mu = theta.cos();
                    let mut tol = super::exact::tests_support::tolerance(&k, &density);
                    tol.rel *= 1e-2;
                    let a = super::exact::tests_support::bessel(mu, &k, &density, tol);
                    let b = super::exact::tests_support::axis(mu, &k, &density, tol);
                    // Below the absolute floor (far below the horizon) only
                    // absolute agreement is asked for.
                    assert!(
                        (a - b).abs() < 1e-12 * a.max(b) + tol.abs,
                        "ℓ={ell} θ={theta}: {a} {b}"
                    );
                }
            }
        }
    }

    /// Phong (frame about r) against the local-frame brute force, for lobes
    /// smooth enough for the brute force to converge.
    #[test]
    fn phong_means_match_brute_force_2d() {
        for (m, theta_r) in [(5.0, 0.3), (20.0, 1.2), (8.0, FRAC_PI_2)] {
            let density = Density::Phong {
                exponent: m,
                mirror_elevation: theta_r,
            };
            for kernel in [
                Kernel::new(KernelKind::SquaredExponential, 0.3, 1.0, 0.0).unwrap(),
                Kernel::new(KernelKind::Matern52, 0.5, 1.0, 0.0).unwrap(),
            ] {
                for (theta, phi) in [(0.0, 0.0), (0.5, 0.3), (1.2, 2.5), (1.5, -0.2)] {
                    let w = direction(theta, phi);
                    assert_matches_brute_force(w, &kernel, &density, &[theta_r.cos()], 1024, 1e-9);
                }
            }
        }
    }

    /// A sharp lobe (m = 2000, angular width ~0.02) under a wide SE kernel
    /// (ℓ = 1): `z(r) ≈ σ²∫p (1 − E[d²]/(2ℓ²))` with `E[d²] ≈ E[α²] ≈ 2/m`.
    #[test]
    fn sharp_lobe_means_approach_their_limits() {
        let density = Density::Phong {
            exponent: 2000.0,
            mirror_elevation: 0.6,
        };
        let r = density.mirror_direction();
        let mass = density.integral();
        let k = Kernel::new(KernelKind::SquaredExponential, 1.0, 1.0, 0.0).unwrap();
        let z = kernel_means(&[r], &k, &density, KernelMeanMethod::Exact).unwrap()[0];
        // SE of width 1 over a lobe of angular radius ~0.02: 1 − O(1e-3).
        assert!(z < mass && z > 0.999 * mass, "{z} {mass}");
        // Second moment check: 1 − z/mass ≈ E[α²]/(2ℓ²) with E[α²] ≈ 2/(m+2)
        // for a normalised cos^m lobe (small-angle Gaussian approximation).
        let predicted = 1.0 / (2000.0 + 2.0);
        assert!(((1.0 - z / mass) / predicted - 1.0).abs() < 0.05);
    }

    /// `V₀` for Phong by the 3-D correlation reduction against a direct
    /// product-rule double sum over a fine grid (smooth case).
    #[test]
    fn phong_prior_variance_matches_double_sum() {
        let density = Density::Phong {
            exponent: 6.0,
            mirror_elevation: 0.4,
        };
        let k = Kernel::new(KernelKind::SquaredExponential, 0.6, 1.0, 0.0).unwrap();
        let v0 = prior_variance(&k, &density, KernelMeanMethod::Exact).unwrap();
        let rule = GaussLegendre::new(48);
        let n_phi = 64;
        let mut nodes = Vec::new();
        for (x, wx) in rule.nodes.iter().zip(&rule.weights) {
            let mu = 0.5 * (x + 1.0);
            let s = (1.0 - mu * mu).sqrt();
            for j in 0..n_phi {
                let phi = TAU * j as f64 / n_phi as f64;
                let v = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
                nodes.push((v, 0.5 * wx * TAU / n_phi as f64 * density.eval(v)));
            }
        }
        let mut sum = 0.0;
        for (a, wa) in &nodes {
            for (b, wb) in &nodes {
                sum += wa * wb * k.eval(*a, *b);
            }
        }
        assert!((v0 / sum - 1.0).abs() < 1e-9, "{v0} {sum}");
    }

    /// The SG approximation is close for sharp lobes and long lengthscales
    /// (figures in docs/BENCHMARKS.md) and refuses non-SG kernels.
    #[test]
    fn spherical_gaussian_means_are_close_for_sharp_lobes() {
        let dirs: Vec<DVec3> = [(0.6, 0.0), (0.5, 0.1), (0.9, -0.3), (0.2, 2.0)]
            .iter()
            .map(|&(t, p)| direction(t, p))
            .collect();
        let density = Density::Phong {
            exponent: 1000.0,
            mirror_elevation: 0.6,
        };
        let k = Kernel::new(KernelKind::SquaredExponential, 0.5, 1.0, 0.0).unwrap();
        let exact = kernel_means(&dirs, &k, &density, KernelMeanMethod::Exact).unwrap();
        let sg = kernel_means(&dirs, &k, &density, KernelMeanMethod::SphericalGaussian).unwrap();
        let zmax = exact.iter().fold(0.0f64, |a, b| a.max(*b));
        for (e, s) in exact.iter().zip(&sg) {
            assert!((e - s).abs() < 1e-3 * zmax, "{e} {s}");
        }
        let v = prior_variance(&k, &density, KernelMeanMethod::Exact).unwrap();
        let v_sg = prior_variance(&k, &density, KernelMeanMethod::SphericalGaussian).unwrap();
        assert!((v_sg / v - 1.0).abs() < 1e-4);
        let matern = Kernel::new(KernelKind::Matern32, 0.5, 1.0, 0.0).unwrap();
        assert!(matches!(
            kernel_means(
                &dirs,
                &matern,
                &density,
                KernelMeanMethod::SphericalGaussian
            ),
            Err(BmcError::Unsupported { .. })
        ));
    }
}
