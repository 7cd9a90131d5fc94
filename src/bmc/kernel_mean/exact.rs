//! Kernel means and prior variances by deterministic high-order quadrature.
//!
//! Three reductions, each integrating in coordinates where the integrand's
//! features (kernel peak, lobe peak, horizon clip) sit on panel boundaries:
//!
//! - **SE kernel, Uniform/Lambert density** (bmc-math.md §4): the azimuth is
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
//!   (`u = cos α`, azimuth `ψ`) the lobe is `u^m`, the clip is an arc
//!   `|ψ| ≤ γ₀(u)` (the cosine `A + B cos ψ` vanishes at its ends), and the
//!   kernel peak sits at `(u_i, ψ_i)`: a nested adaptive 2-D integral.
//!
//! `V₀ = ∫ z(ω) p(ω) dω` reuses these: 1-D over `μ` for the rotation-invariant
//! densities, 2-D over `(u, ψ)` for Phong (symmetric in `ψ`, so `ψ ≥ 0` only).

use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, PI};

use glam::DVec3;

use crate::bmc::bessel::i0_scaled;
use crate::bmc::density::{Density, clipped_cosine_arc, phong_normalisation, positive_half_arc};
use crate::bmc::integrate::{Tolerance, adaptive, adaptive_split};
use crate::bmc::kernel::{Kernel, KernelKind};

/// Relative tolerance requested of every exact kernel mean. The adaptive
/// driver's error estimate is that of the coarser rule, so the delivered
/// accuracy is far better (measured ≤ 1e-12 in the tests).
const REL_TOL: f64 = 1e-10;

/// Relative tolerance of the outer integral of `V₀ = ∫ z p`, whose integrand
/// is smooth at the scale of the kernel and of the lobe.
const PRIOR_REL_TOL: f64 = 1e-8;

/// Absolute floor, as a fraction of `σ² ∫p` (the largest possible kernel
/// mean): kernel means below ~1e-15 of that are not resolved relatively.
const ABS_FLOOR: f64 = 1e-16;

/// Kernel-width multiples placed as breaks so narrow kernels are never
/// stepped over by the first panels.
const WIDTHS: [f64; 2] = [2.0, 6.0];

fn tolerance(kernel: &Kernel, density: &Density, rel: f64) -> Tolerance {
    Tolerance {
        rel,
        abs: ABS_FLOOR * kernel.variance * density.integral(),
    }
}

/// Exact `z(ω) = ∫_H k(ω, ω') p(ω') dω'` for a unit direction `ω` (local frame;
/// may lie anywhere on the sphere).
pub(crate) fn kernel_mean(w: DVec3, kernel: &Kernel, density: &Density) -> f64 {
    kernel_mean_with(w, kernel, density, tolerance(kernel, density, REL_TOL))
}

fn kernel_mean_with(w: DVec3, kernel: &Kernel, density: &Density, tol: Tolerance) -> f64 {
    match *density {
        Density::Uniform | Density::Lambert => {
            let mu = w.z.clamp(-1.0, 1.0);
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
        // λ(μ_i μ + s_i s − 1) = −λ |ω_i − ω|²/2 in the φ = 0 plane.
        let e = lambda * (mu_i * mu + s_i * s - 1.0);
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

    /// `(A, B)` of the cosine `A + B cos ψ` on the circle `u`, and `v = sin α`.
    fn cosine(&self, u: f64) -> (f64, f64, f64) {
        let v = (1.0 - u * u).max(0.0).sqrt();
        (u * self.cos_r, v * self.sin_r, v)
    }

    fn direction(&self, u: f64, v: f64, psi: f64) -> DVec3 {
        let (sp, cp) = psi.sin_cos();
        u * self.r + v * (cp * self.e1 + sp * DVec3::Y)
    }

    /// Breaks in `u` for the lobe `u^m` (width `~1/m` in `u`) and the horizon
    /// clip (`u = sin θ_r`, below which the circle dips under the horizon).
    fn u_breaks(&self, m: f64) -> Vec<f64> {
        let mut b = vec![self.sin_r];
        b.extend([3.0, 30.0].map(|k| 1.0 - k / (m + 1.0)));
        b
    }
}

/// Phong density (any kernel), 2-D in the frame about `r`.
fn lobe_mean(w: DVec3, kernel: &Kernel, density: &Density, m: f64, tol: Tolerance) -> f64 {
    let frame = LobeFrame::new(density);
    let u_i = w.dot(frame.r).clamp(-1.0, 1.0);
    let psi_i = w.y.atan2(w.dot(frame.e1));
    let alpha_i = u_i.acos();
    let ell = kernel.lengthscale;
    let norm = phong_normalisation(m);
    let inner_tol = tol.scaled(norm).nested(1.0);
    let f = |u: f64| {
        let (a, b, v) = frame.cosine(u);
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
        u.powf(m) * adaptive_split(&g, -half, half, &breaks, inner_tol)
    };
    let mut breaks = frame.u_breaks(m);
    breaks.push(u_i);
    for k in WIDTHS {
        for t in [alpha_i - k * ell, alpha_i + k * ell] {
            breaks.push(t.clamp(0.0, PI).cos());
        }
    }
    norm * adaptive_split(&f, 0.0, 1.0, &breaks, tol.scaled(norm))
}

/// Exact prior variance `V₀ = ∫∫ k(ω, ω') p(ω) p(ω') dω dω'`.
pub(crate) fn prior_variance(kernel: &Kernel, density: &Density) -> f64 {
    // Outer panels need less than the inner ones: the outer integrand z(ω)
    // is smooth at the scale of the kernel and of the lobe.
    let base = tolerance(kernel, density, 10.0 * PRIOR_REL_TOL);
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
        Density::Phong { exponent: m, .. } => {
            let frame = LobeFrame::new(density);
            let norm = phong_normalisation(m);
            let inner_outer = outer.scaled(norm).nested(1.0);
            let f = |u: f64| {
                let (a, b, v) = frame.cosine(u);
                let half = positive_half_arc(a, b);
                if half <= 0.0 {
                    return 0.0;
                }
                let g = |psi: f64| {
                    let w = frame.direction(u, v, psi);
                    kernel_mean_with(w, kernel, density, base) * (a + b * psi.cos())
                };
                // z(ω) p(ω) is even in ψ (the density is symmetric about the
                // plane of n and r, the kernel is isotropic).
                2.0 * u.powf(m) * adaptive(&g, 0.0, half, inner_outer)
            };
            norm * adaptive_split(&f, 0.0, 1.0, &frame.u_breaks(m), outer.scaled(norm))
        }
    }
}
