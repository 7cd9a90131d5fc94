//! Kernel means `z(ω) = ∫_H k(ω, ω') p(ω') dω'` and the prior variance
//! `V₀ = ∫∫ k(ω, ω') p(ω) p(ω') dω dω'` (bmc-math.md §3–4).
//!
//! [`KernelMeanMethod::Exact`] integrates by deterministic adaptive quadrature
//! (see [`exact`]) to ~1e-12 relative; [`KernelMeanMethod::SphericalGaussian`]
//! uses the closed-form SG approximation of Marques et al. 2013 (SE kernel
//! only), whose measured error is documented in `docs/BENCHMARKS.md`.

mod exact;
mod spherical_gaussian;

use glam::DVec3;
use rayon::prelude::*;

use super::density::Density;
use super::error::BmcError;
use super::kernel::Kernel;
use super::quadrature::KernelMeanMethod;

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
        KernelMeanMethod::Exact => Ok(directions
            .par_iter()
            .map(|&w| exact::kernel_mean(w, kernel, density))
            .collect()),
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
