//! Exponentially scaled modified Bessel function `I₀(x) e^{−x}`.
//!
//! Needed by the 1-D kernel-mean formula (docs/math.md §4), whose azimuthal
//! integral is `∫₀^{2π} e^{a cos φ} dφ = 2π I₀(a)` with `a` up to `1/ℓ²`
//! (10⁴ for ℓ = 0.01), where `I₀` itself overflows. No maintained Rust crate
//! offered the scaled form, so it is evaluated here from two textbook series
//! (Abramowitz & Stegun, *Handbook of Mathematical Functions*, 1964):
//! - `x ≤ 30`: the power series 9.6.10, `I₀(x) = Σ_k (x²/4)^k/(k!)²`; all terms
//!   are positive, so there is no cancellation (error a few ulps).
//! - `x > 30`: the asymptotic expansion 9.7.1,
//!   `I₀(x) e^{−x} ~ (2πx)^{−1/2} Σ_k [(2k−1)!!]² / (k! (8x)^k)`; its smallest
//!   term, reached near `k ≈ 2x`, is about `e^{−2x} < 10⁻²⁶`, so truncation
//!   at machine precision is always possible.

use std::f64::consts::PI;

/// Switch-over point between the two series (see the module docs).
const SERIES_LIMIT: f64 = 30.0;

/// `I₀(x) e^{−|x|}` for any finite `x` (`I₀` is even). Relative error ≲ 1e-15.
pub fn i0_scaled(x: f64) -> f64 {
    let x = x.abs();
    if x <= SERIES_LIMIT {
        let q = 0.25 * x * x;
        let mut term = 1.0;
        let mut sum = 1.0;
        let mut k = 1.0;
        while term > 1e-17 * sum {
            term *= q / (k * k);
            sum += term;
            k += 1.0;
        }
        sum * (-x).exp()
    } else {
        let mut term = 1.0;
        let mut sum = 1.0;
        let mut k = 1.0;
        loop {
            let next = term * (2.0 * k - 1.0f64).powi(2) / (8.0 * k * x);
            if next < 1e-17 * sum || next > term {
                break;
            }
            term = next;
            sum += term;
            k += 1.0;
        }
        sum / (2.0 * PI * x).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::integrate::{Tolerance, adaptive};

    /// Integral representation `I₀(x)e^{−x} = (1/π)∫₀^π e^{x(cos t − 1)} dt`
    /// (A&S 9.6.16), evaluated independently by adaptive quadrature.
    fn by_integral(x: f64) -> f64 {
        let tol = Tolerance {
            rel: 1e-14,
            abs: 0.0,
        };
        adaptive(&|t: f64| (x * (t.cos() - 1.0)).exp(), 0.0, PI, tol) / PI
    }

    #[test]
    fn matches_reference_values() {
        // I₀(1) and I₀(10) from A&S Table 9.8 (there given scaled by e^{−x}).
        assert!((i0_scaled(1.0) / ((-1f64).exp() * 1.266_065_877_752_008_4) - 1.0).abs() < 1e-15);
        assert!((i0_scaled(10.0) / ((-10f64).exp() * 2_815.716_628_466_254) - 1.0).abs() < 1e-14);
        assert_eq!(i0_scaled(0.0), 1.0);
    }

    #[test]
    fn matches_integral_representation_across_both_branches() {
        for x in [1e-8, 0.3, 2.0, 7.5, 29.9, 30.1, 45.0, 200.0, 1e4] {
            let got = i0_scaled(x);
            let want = by_integral(x);
            assert!((got / want - 1.0).abs() < 2e-14, "x={x}: {got} vs {want}");
            assert_eq!(i0_scaled(-x), got);
        }
    }
}
