//! Closed-form kernel means under a spherical-Gaussian (SG) approximation of
//! the density (Marques et al., "Spherical Fibonacci Point Sets for
//! Illumination Integrals", CGF 2013, §6; SG algebra in docs/math.md §4).
//!
//! The density is replaced by one SG on the whole sphere: the clamped cosine
//! by `a_c e^{λ_c(ω·n − 1)}`, the Phong lobe `max(0, ω·r)^m` by
//! `a_m e^{λ_m(ω·r − 1)}`, the uniform hemisphere by `a_u e^{λ_u(ω·n − 1)}`,
//! each fitted here by least squares on the sphere (then rescaled to the exact
//! mass `∫_H p`), and products of SGs are
//! SGs. The SE kernel is itself an SG (`λ = 1/ℓ²`, amplitude `σ²`), so every
//! kernel mean is the integral of a product of two SGs over S²: closed form.
//! `V₀` is then a 1-D integral over `ω·μ_p`, evaluated by quadrature. The
//! approximation is only as good as the SG fit of the density; its measured
//! error against the exact means is in `docs/BENCHMARKS.md`.

use std::f64::consts::{FRAC_1_PI, TAU};

use glam::DVec3;

use crate::bmc::density::{Density, phong_normalisation};
use crate::bmc::error::BmcError;
use crate::bmc::integrate::{Tolerance, adaptive_split};
use crate::bmc::kernel::{Kernel, KernelKind};

/// `a e^{λ(μ·ω − 1)}`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SphericalGaussian {
    pub axis: DVec3,
    pub sharpness: f64,
    pub amplitude: f64,
}

impl SphericalGaussian {
    #[cfg(test)]
    pub fn eval(&self, w: DVec3) -> f64 {
        self.amplitude * (self.sharpness * (self.axis.dot(w) - 1.0)).exp()
    }

    /// `∫_{S²} G = 2π a (1 − e^{−2λ})/λ` (docs/math.md §4).
    pub fn integral(&self) -> f64 {
        TAU * self.amplitude * sphere_factor(self.sharpness)
    }

    /// Product SG: `λ_m μ_m = λ₁μ₁ + λ₂μ₂`, `a_m = a₁a₂ e^{λ_m − λ₁ − λ₂}`.
    pub fn product(&self, other: &SphericalGaussian) -> SphericalGaussian {
        let v = self.sharpness * self.axis + other.sharpness * other.axis;
        let lambda = v.length();
        let axis = if lambda > 0.0 { v / lambda } else { DVec3::Z };
        SphericalGaussian {
            axis,
            sharpness: lambda,
            amplitude: self.amplitude
                * other.amplitude
                * (lambda - self.sharpness - other.sharpness).exp(),
        }
    }
}

/// `(1 − e^{−2λ})/λ`, with its limit 2 at `λ → 0`.
fn sphere_factor(lambda: f64) -> f64 {
    if lambda < 1e-12 {
        2.0
    } else {
        -(-2.0 * lambda).exp_m1() / lambda
    }
}

/// Least-squares SG fit `a e^{λ(μ − 1)}` of a zonal function `f(μ)` that
/// vanishes for `μ < 0`, in `L²(S²)`: for fixed `λ` the best amplitude is
/// `⟨f, g⟩/⟨g, g⟩`, and `λ` maximises `⟨f, g⟩²/⟨g, g⟩` (golden section on
/// `ln λ`). `breaks` are features of `f` in `μ ∈ [0, 1]`.
fn fit_zonal(f: &dyn Fn(f64) -> f64, breaks: &[f64]) -> (f64, f64) {
    let tol = Tolerance {
        rel: 1e-12,
        abs: 0.0,
    };
    // Per-steradian inner products, up to the common factor 2π.
    let fg = |lambda: f64| {
        adaptive_split(
            &|mu: f64| f(mu) * (lambda * (mu - 1.0)).exp(),
            0.0,
            1.0,
            breaks,
            tol,
        )
    };
    let gg = |lambda: f64| -(-4.0 * lambda).exp_m1() / (2.0 * lambda);
    let score = |log_lambda: f64| {
        let l = log_lambda.exp();
        let p = fg(l);
        p * p / gg(l)
    };
    let (mut lo, mut hi) = ((1e-3f64).ln(), (1e8f64).ln());
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - ratio * (hi - lo);
    let mut x2 = lo + ratio * (hi - lo);
    let (mut s1, mut s2) = (score(x1), score(x2));
    while hi - lo > 1e-10 {
        if s1 < s2 {
            lo = x1;
            x1 = x2;
            s1 = s2;
            x2 = lo + ratio * (hi - lo);
            s2 = score(x2);
        } else {
            hi = x2;
            x2 = x1;
            s2 = s1;
            x1 = hi - ratio * (hi - lo);
            s1 = score(x1);
        }
    }
    let lambda = (0.5 * (lo + hi)).exp();
    (lambda, fg(lambda) / gg(lambda))
}

/// The clamped cosine `max(0, μ)` as an SG about the normal: `(λ_c, a_c)`.
pub(crate) fn cosine_fit() -> (f64, f64) {
    use std::sync::OnceLock;
    static FIT: OnceLock<(f64, f64)> = OnceLock::new();
    *FIT.get_or_init(|| fit_zonal(&|mu| mu, &[]))
}

/// One SG approximating the density on the whole sphere, its amplitude
/// rescaled so that `∫_{S²} p_SG = ∫_H p` exactly: the least-squares fit alone
/// misses the mass by 2–15 %, which would bias every long-lengthscale kernel
/// mean by as much (kernel means tend to `σ² ∫p` as `ℓ → ∞`).
pub(crate) fn density_sg(density: &Density) -> SphericalGaussian {
    let mut p = fitted_density_sg(density);
    p.amplitude *= density.integral() / p.integral();
    p
}

fn fitted_density_sg(density: &Density) -> SphericalGaussian {
    let about = |axis: DVec3, (sharpness, amplitude): (f64, f64)| SphericalGaussian {
        axis,
        sharpness,
        amplitude,
    };
    match *density {
        Density::Uniform => {
            let (l, a) = fit_zonal(&|_| 1.0, &[]);
            about(DVec3::Z, (l, a / TAU))
        }
        Density::Lambert => {
            let (l, a) = cosine_fit();
            about(DVec3::Z, (l, a * FRAC_1_PI))
        }
        Density::Phong { exponent: m, .. } => {
            let breaks: Vec<f64> = [1.0, 4.0, 16.0, 64.0]
                .iter()
                .map(|k| 1.0 - k / (m + 1.0))
                .collect();
            let lobe = about(
                density.mirror_direction(),
                fit_zonal(&|u: f64| u.powf(m), &breaks),
            );
            let mut p = lobe.product(&about(DVec3::Z, cosine_fit()));
            p.amplitude *= phong_normalisation(m);
            p
        }
    }
}

fn kernel_sg(kernel: &Kernel, axis: DVec3) -> Result<SphericalGaussian, BmcError> {
    if kernel.kind != KernelKind::SquaredExponential {
        return Err(BmcError::Unsupported {
            method: "spherical_gaussian",
            what: format!(
                "{:?} kernels (only squared_exponential is an SG)",
                kernel.kind
            ),
        });
    }
    Ok(SphericalGaussian {
        axis,
        sharpness: 1.0 / (kernel.lengthscale * kernel.lengthscale),
        amplitude: kernel.variance,
    })
}

/// SG-approximate kernel means for the given directions.
pub(crate) fn kernel_means(
    directions: &[DVec3],
    kernel: &Kernel,
    density: &Density,
) -> Result<Vec<f64>, BmcError> {
    kernel_sg(kernel, DVec3::Z)?;
    let p = density_sg(density);
    directions
        .iter()
        .map(|&w| Ok(kernel_sg(kernel, w)?.product(&p).integral()))
        .collect()
}

/// SG-approximate `V₀ = ∫∫ k p_SG p_SG` over S² × S².
///
/// With `c = ω·μ_p` and `R(c) = |λ_k ω + λ_p μ_p|`, the inner integral is
/// `z(ω) = 2π σ² a_p e^{R − λ_k − λ_p}(1 − e^{−2R})/R`, and
/// `V₀ = 2π a_p ∫_{−1}^{1} e^{λ_p(c − 1)} z(c) dc`.
pub(crate) fn prior_variance(kernel: &Kernel, density: &Density) -> Result<f64, BmcError> {
    let k = kernel_sg(kernel, DVec3::Z)?;
    let p = density_sg(density);
    let (lk, lp) = (k.sharpness, p.sharpness);
    let f = |c: f64| {
        let r = (lk * lk + lp * lp + 2.0 * lk * lp * c).max(0.0).sqrt();
        (lp * (c - 1.0) + r - lk - lp).exp() * sphere_factor(r)
    };
    let width = 1.0 / (lk + lp);
    let breaks = [1.0 - width, 1.0 - 8.0 * width, 1.0 - 64.0 * width];
    let tol = Tolerance {
        rel: 1e-13,
        abs: 0.0,
    };
    let integral = adaptive_split(&f, -1.0, 1.0, &breaks, tol);
    Ok(TAU * TAU * p.amplitude * p.amplitude * k.amplitude * integral)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::integrate::adaptive;

    #[test]
    fn cosine_fit_is_close_to_the_published_lobe() {
        // Wang et al. 2009 quote λ ≈ 2.133, a ≈ 1.17 for the cosine SG; a
        // least-squares fit on the sphere lands nearby.
        let (l, a) = cosine_fit();
        assert!((l - 2.133).abs() < 0.3, "{l}");
        assert!((a - 1.17).abs() < 0.1, "{a}");
    }

    #[test]
    fn product_and_integral_agree_with_quadrature() {
        let g1 = SphericalGaussian {
            axis: DVec3::new(0.0, 0.6, 0.8),
            sharpness: 3.0,
            amplitude: 2.0,
        };
        let g2 = SphericalGaussian {
            axis: DVec3::new(0.6, 0.0, 0.8),
            sharpness: 7.0,
            amplitude: 0.5,
        };
        let prod = g1.product(&g2);
        let w = DVec3::new(0.3, 0.2, 0.5).normalize();
        assert!((prod.eval(w) / (g1.eval(w) * g2.eval(w)) - 1.0).abs() < 1e-13);
        // ∫ over the sphere of an SG about z: 2π a ∫ e^{λ(μ−1)} dμ.
        let tol = Tolerance {
            rel: 1e-14,
            abs: 0.0,
        };
        let direct = TAU * 2.0 * adaptive(&|mu| (3.0 * (mu - 1.0)).exp(), -1.0, 1.0, tol);
        assert!((g1.integral() / direct - 1.0).abs() < 1e-13);
    }
}
