//! Kernel means and prior variances by deterministic high-order quadrature.
//!
//! Three reductions, each integrating in coordinates where the integrand's
//! features (kernel peak, lobe peak, horizon clip) sit on panel boundaries:
//!
//! - **SE kernel, Uniform/Lambert density** (docs/math.md §4): the azimuth is
//!   integrated in closed form, `∫₀^{2π} e^{a cos φ} dφ = 2π I₀(a)`, leaving
//!   `z(μ_i) = σ² ∫₀¹ e^{λ(μ_i μ + s_i s − 1)} Ĩ₀(λ s_i s) · 2π p(μ) dμ`
//!   with `λ = 1/ℓ²`, `μ = cos θ`, `s = sin θ` and `Ĩ₀(x) = I₀(x)e^{−x}`; the
//!   exponent `λ(cos(θ − θ_i) − 1) ≤ 0` never overflows.
//! - **Any kernel, Uniform/Lambert density**: in a frame about `ω_i` (polar
//!   angle `β`, azimuth `γ`) the kernel depends on `β` only and the clipped
//!   density integrates over `γ` in closed form ([`clipped_cosine_arc`]):
//!   `z = ∫₀^π k(β) sin β g(β) dβ`; `g` has kinks where the circle of radius
//!   `β` touches the horizon (`β = |π/2 − θ_i|`, `π/2 + θ_i`), which are breaks.
//! - **Phong density, any kernel**: in a frame about the mirror direction `r`
//!   (angle `α`, `u = cos α`, azimuth `ψ`) the lobe is `u^m`, the clip is an arc
//!   `|ψ| ≤ γ₀(α)` (the cosine `A + B cos ψ` vanishes at its ends), and the
//!   kernel peak sits at `(α_i, ψ_i)`: a nested adaptive 2-D integral.
//!
//! `V₀`: for the rotation-invariant densities `V₀ = ∫ z(μ) 2π p(μ) dμ`, 1-D
//! over exact `z`; for Phong a 3-D reduction whose innermost azimuthal
//! integral is closed-form ([`phong_prior_variance`]).

use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, PI, TAU};

use glam::DVec3;

use crate::bmc::bessel::i0_scaled;
use crate::bmc::density::{Density, clipped_cosine_arc, phong_normalisation, positive_half_arc};
use crate::bmc::integrate::{Tolerance, adaptive, adaptive_split};
use crate::bmc::kernel::{Kernel, KernelKind};

/// Relative tolerance requested of the 2-D (Phong) kernel means; 1-D ones ask
/// for 1e-12. The adaptive driver's error estimate is that of the coarser
/// rule, so the delivered accuracy is better (measured 1e-14 … 2e-11 against
/// brute force, `docs/BENCHMARKS.md`).
const REL_TOL: f64 = 1e-10;

/// Relative tolerance of the outermost integral of `V₀`.
const PRIOR_REL_TOL: f64 = 1e-10;

/// Absolute floor, as a fraction of `σ² ∫p` (the largest possible kernel
/// mean): kernel means below ~1e-15 of that are not resolved relatively.
const ABS_FLOOR: f64 = 1e-16;

/// Kernel-width multiples placed as breaks so narrow kernels are never
/// stepped over by the first panels.
const WIDTHS: [f64; 1] = [3.0];

fn tolerance(kernel: &Kernel, density: &Density, rel: f64) -> Tolerance {
    Tolerance {
        rel,
        abs: ABS_FLOOR * kernel.variance * density.integral(),
    }
}

/// Exact `z(ω) = ∫_H k(ω, ω') p(ω') dω'` for unit directions `ω` (local
/// frame; they may lie anywhere on the sphere). Sequential, like the
/// factorisation (see `bmc::factorisation`): this runs inside single-flight
/// cache initialisers, which parallelise across requests already.
pub(crate) fn kernel_means(directions: &[DVec3], kernel: &Kernel, density: &Density) -> Vec<f64> {
    let tol = tolerance(kernel, density, REL_TOL);
    directions
        .iter()
        .map(|&w| kernel_mean_with(w, kernel, density, tol))
        .collect()
}

fn kernel_mean_with(w: DVec3, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
    match *density {
        Density::Uniform | Density::Lambert => {
            let mu = w.z.clamp(-1.0, 1.0);
            // 1-D integrals are cheap: ask for two more digits.
            let tol = Tolerance {
                rel: tol.rel * 1e-2,
                abs: tol.abs,
            };
            if kernel.kind == KernelKind::SquaredExponential {
                bessel_mean(mu, kernel, density, tol)
            } else {
                axis_mean(mu, kernel, density, tol)
            }
        }
        Density::Phong { exponent, .. } => lobe_mean(w, kernel, density, exponent, tol),
    }
}

/// `2π p(μ)` for the rotation-invariant densities (`p` per steradian at `cos θ = μ`).
fn zonal_density(density: &Density, mu: f64) -> f64 {
    match density {
        Density::Lambert => 2.0 * mu,
        _ => 1.0,
    }
}

/// SE kernel with a Uniform/Lambert density by the 1-D Bessel formula.
fn bessel_mean(mu_i: f64, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
    let lambda = 1.0 / (kernel.lengthscale * kernel.lengthscale);
    let s_i = (1.0 - mu_i * mu_i).max(0.0).sqrt();
    let theta_i = mu_i.acos();
    let f = |mu: f64| {
        let s = (1.0 - mu * mu).max(0.0).sqrt();
        let a = lambda * s_i * s;
        // λ(μ_i μ + s_i s − 1) = −λ |ω_i − ω|²/2 in the φ = 0 plane; ≤ 0 up
        // to rounding, which must not be amplified by a large λ.
        let e = (lambda * (mu_i * mu + s_i * s - 1.0)).min(0.0);
        e.exp() * i0_scaled(a) * zonal_density(density, mu)
    };
    let mut breaks = vec![mu_i];
    for k in WIDTHS {
        for t in [
            theta_i - k * kernel.lengthscale,
            theta_i + k * kernel.lengthscale,
        ] {
            breaks.push(t.clamp(0.0, PI).cos());
        }
    }
    kernel.variance * adaptive_split(&f, 0.0, 1.0, &breaks, tol.scaled(kernel.variance))
}

/// Any kernel with a Uniform/Lambert density, in the frame about `ω_i`.
fn axis_mean(mu_i: f64, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
    let theta_i = mu_i.acos();
    let s_i = theta_i.sin();
    let lambert = matches!(density, Density::Lambert);
    let f = |beta: f64| {
        let (sb, cb) = beta.sin_cos();
        let a = mu_i * cb;
        let b = s_i * sb;
        let g = if lambert {
            clipped_cosine_arc(a, b) * FRAC_1_PI
        } else {
            positive_half_arc(a, b) * FRAC_1_PI
        };
        kernel.eval_angle(beta) * sb * g
    };
    let top = (FRAC_PI_2 + theta_i).min(PI);
    let mut breaks = vec![(FRAC_PI_2 - theta_i).abs()];
    breaks.extend(WIDTHS.iter().map(|k| k * kernel.lengthscale));
    adaptive_split(&f, 0.0, top, &breaks, tol)
}

/// Orthonormal frame about the Phong mirror direction `r = (sin θ_r, 0, cos θ_r)`:
/// `ω = u r + v (cos ψ e₁ + sin ψ e₂)` has `cos θ = u cos θ_r + v sin θ_r cos ψ`.
struct LobeFrame {
    r: DVec3,
    e1: DVec3,
    sin_r: f64,
    cos_r: f64,
}

impl LobeFrame {
    fn new(density: &Density) -> LobeFrame {
        let r = density.mirror_direction();
        LobeFrame {
            r,
            e1: DVec3::new(-r.z, 0.0, r.x),
            sin_r: r.x,
            cos_r: r.z,
        }
    }

    /// On the circle at angle `α` from `r`: `(A, B, u, v)` with the cosine
    /// `cos θ = A + B cos ψ`, `u = cos α`, `v = sin α`.
    fn circle(&self, alpha: f64) -> (f64, f64, f64, f64) {
        let (v, u) = alpha.sin_cos();
        (u * self.cos_r, v * self.sin_r, u, v)
    }

    fn direction(&self, u: f64, v: f64, psi: f64) -> DVec3 {
        let (sp, cp) = psi.sin_cos();
        u * self.r + v * (cp * self.e1 + sp * DVec3::Y)
    }

    /// Breaks in `α` for the lobe `cos^m α ≈ e^{−mα²/2}` (width `~1/sqrt(m)`)
    /// and the horizon clip (`α = π/2 − θ_r`, beyond which the circle dips
    /// under the horizon).
    fn alpha_breaks(&self, m: f64) -> Vec<f64> {
        let mut b = vec![FRAC_PI_2 - self.cos_r.acos()];
        b.extend([6.0, 60.0].map(|k: f64| (k / (m + 1.0)).sqrt()));
        b
    }
}

/// Phong density (any kernel), 2-D in the frame about `r`. Integrating over
/// the angle `α` rather than `u = cos α` keeps `sin α` analytic, which matters
/// for grazing `r`, where the circles are clipped right up to `α = 0`.
fn lobe_mean(w: DVec3, kernel: &Kernel, density: &Density, m: f64, tol: Tolerance) -> f64 {
    let frame = LobeFrame::new(density);
    let u_i = w.dot(frame.r).clamp(-1.0, 1.0);
    let psi_i = w.y.atan2(w.dot(frame.e1));
    let alpha_i = u_i.acos();
    let ell = kernel.lengthscale;
    let norm = phong_normalisation(m);
    let outer_tol = tol.scaled(norm);
    let f = |alpha: f64| {
        let (a, b, u, v) = frame.circle(alpha);
        let half = positive_half_arc(a, b);
        if half <= 0.0 {
            return 0.0;
        }
        let g = |psi: f64| kernel.eval(frame.direction(u, v, psi), w) * (a + b * psi.cos());
        // Kernel peak at ψ_i, width ~ℓ/v in ψ.
        let mut breaks = vec![psi_i];
        if v > 0.0 {
            for k in WIDTHS {
                breaks.push(psi_i - k * ell / v);
                breaks.push(psi_i + k * ell / v);
            }
        }
        // Inner errors are weighted by u^m sin α: circles far out in a sharp
        // lobe need no more absolute accuracy than the total asks for.
        let weight = u.powf(m) * v;
        weight * adaptive_split(&g, -half, half, &breaks, outer_tol.scaled(weight))
    };
    let mut breaks = frame.alpha_breaks(m);
    breaks.push(alpha_i);
    for k in WIDTHS {
        breaks.push(alpha_i - k * ell);
        breaks.push(alpha_i + k * ell);
    }
    norm * adaptive_split(&f, 0.0, FRAC_PI_2, &breaks, outer_tol)
}

/// Exact prior variance `V₀ = ∫∫ k(ω, ω') p(ω) p(ω') dω dω'`.
pub(crate) fn prior_variance(kernel: &Kernel, density: &Density) -> f64 {
    let base = tolerance(kernel, density, REL_TOL);
    let outer = Tolerance {
        rel: PRIOR_REL_TOL,
        abs: base.abs * density.integral(),
    };
    match *density {
        Density::Uniform | Density::Lambert => {
            let f = |mu: f64| {
                let s = (1.0 - mu * mu).max(0.0).sqrt();
                let z = kernel_mean_with(DVec3::new(s, 0.0, mu), kernel, density, base);
                z * zonal_density(density, mu)
            };
            adaptive(&f, 0.0, 1.0, outer)
        }
        Density::Phong { exponent: m, .. } => phong_prior_variance(kernel, density, m, outer),
    }
}

/// `V₀` for a Phong density as a 3-D integral. With both directions in the
/// frame about `r`, `ω = (u, ψ)`, `ω' = (u', ψ + δ)`, the kernel depends on
/// `(u, u', δ)` only (`ω·ω' = uu' + vv' cos δ`), so the integral over `ψ` of
/// the two clipped cosines is a closed-form correlation
/// ([`clipped_cosine_correlation`]):
/// `V₀ = N_m² ∫∫ u^m v u'^m v' ∫_{−π}^{π} k(uu' + vv' cos δ) C(u, u', δ) dδ dα' dα`
/// (`u = cos α`, `v = sin α`).
/// The integrand is even in `δ` (mirror symmetry about the `n`–`r` plane) and
/// symmetric in `(α, α')`, so only `δ ≥ 0`, `α' ≥ α` is integrated.
fn phong_prior_variance(kernel: &Kernel, density: &Density, m: f64, tol: Tolerance) -> f64 {
    let frame = LobeFrame::new(density);
    let norm = phong_normalisation(m);
    let ell = kernel.lengthscale;
    let tol = tol.scaled(norm * norm);
    let alpha_breaks = frame.alpha_breaks(m);
    let f = |alpha: f64| {
        let (a, b, u, v) = frame.circle(alpha);
        let g = positive_half_arc(a, b);
        if g <= 0.0 {
            return 0.0;
        }
        let weight = 2.0 * u.powf(m) * v;
        let middle_tol = tol.scaled(weight);
        let inner = |alpha2: f64| {
            let (a2, b2, u2, v2) = frame.circle(alpha2);
            let g2 = positive_half_arc(a2, b2);
            if g2 <= 0.0 {
                return 0.0;
            }
            let h = |delta: f64| {
                let c = u * u2 + v * v2 * delta.cos();
                let chord = (2.0 - 2.0 * c).max(0.0).sqrt();
                kernel.eval_chord(chord)
                    * clipped_cosine_correlation((a, b, g), (a2, b2, g2), delta)
            };
            let mut breaks = vec![(g - g2).abs(), g + g2, TAU - g - g2];
            let vv = (v * v2).sqrt();
            if vv > 0.0 {
                breaks.extend(WIDTHS.iter().map(|k| k * ell / vv));
            }
            let weight = 2.0 * u2.powf(m) * v2;
            weight * adaptive_split(&h, 0.0, PI, &breaks, middle_tol.scaled(weight))
        };
        let mut breaks = alpha_breaks.clone();
        breaks.extend(WIDTHS.iter().map(|k| alpha + k * ell));
        // The integrand is symmetric in (α, α'): integrate α' > α, twice.
        weight * adaptive_split(&inner, alpha, FRAC_PI_2, &breaks, middle_tol)
    };
    norm * norm * adaptive_split(&f, 0.0, FRAC_PI_2, &alpha_breaks, tol)
}

/// `C(δ) = ∫_{−π}^{π} max(0, a + b cos ψ) · max(0, a₂ + b₂ cos(ψ + δ)) dψ`
/// for two circles with positive arcs `|ψ| ≤ g` and `|ψ + δ| ≤ g₂` (`g`, `g₂`
/// from [`positive_half_arc`]). On the overlap of the arcs the product is a
/// trigonometric polynomial with the closed-form antiderivative below; the
/// second arc is shifted by `2πk`, `k ∈ {−1, 0, 1}`, to account for wrap-around
/// (the product is 2π-periodic, and the shifted copies of the second arc are
/// disjoint, so each point of the first arc is counted once, full circles
/// included).
fn clipped_cosine_correlation(
    (a, b, g): (f64, f64, f64),
    (a2, b2, g2): (f64, f64, f64),
    delta: f64,
) -> f64 {
    let (sd, cd) = delta.sin_cos();
    // P(ψ) = (a + b cos ψ)(a₂ + b₂ cos δ cos ψ − b₂ sin δ sin ψ)
    let antiderivative = |x: f64| {
        let (s, c) = x.sin_cos();
        let (s2, c2) = (2.0 * x).sin_cos();
        a * a2 * x
            + (a * b2 * cd + a2 * b) * s
            + a * b2 * sd * c
            + b * b2 * cd * (0.5 * x + 0.25 * s2)
            + b * b2 * sd * 0.25 * c2
    };
    let (lo1, hi1) = (-g, g);
    let mut total = 0.0;
    for k in [-1.0, 0.0, 1.0] {
        let shift = k * TAU;
        let lo = lo1.max(-delta - g2 + shift);
        let hi = hi1.min(-delta + g2 + shift);
        if hi > lo {
            total += antiderivative(hi) - antiderivative(lo);
        }
    }
    total.max(0.0)
}

#[cfg(test)]
pub(super) mod tests_support {
    //! The individual reductions, for cross-checks in `kernel_mean::tests`.
    use super::*;

    pub fn tolerance(kernel: &Kernel, density: &Density) -> Tolerance {
        super::tolerance(kernel, density, REL_TOL)
    }
    pub fn bessel(mu: f64, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
        bessel_mean(mu, kernel, density, tol)
    }
    pub fn axis(mu: f64, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
        axis_mean(mu, kernel, density, tol)
    }
}
