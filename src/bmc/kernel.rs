//! Covariance kernels on the sphere, functions of the chordal distance
//! `d = |ω − ω'| = sqrt(2 − 2 ω·ω')` (docs/math.md §2).
//!
//! A kernel that is positive definite on R³ stays positive definite when
//! restricted to the sphere, so these are valid GP covariances on S².

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::error::BmcError;

/// Smallest accepted lengthscale: far below the spacing of the densest
/// sample set (~0.03 at N = 8192), and keeps `1/ℓ²` well inside `f64` range.
pub const MIN_LENGTHSCALE: f64 = 1e-2;
/// Largest accepted lengthscale: beyond it every kernel matrix is the
/// all-`σ²` matrix to machine precision (chords are at most 2).
pub const MAX_LENGTHSCALE: f64 = 1e3;
/// Largest accepted prior variance `σ²` and noise `σ_n²` (units of `f`²).
/// Radiance² never comes near it, and it keeps every sum and product the
/// factorisation forms (`σ² + σ_n²`, the relative jitter, `Σ z_i w_i σ²`)
/// finite: at `1e308` the diagonal overflowed to `inf` and the jitter search
/// never ended.
pub const MAX_VARIANCE: f64 = 1e100;

/// Shape of the covariance as a function of `d/ℓ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum KernelKind {
    /// `σ² exp(−d²/(2ℓ²)) = σ² exp((ω·ω' − 1)/ℓ²)`: a spherical Gaussian
    /// with sharpness `λ = 1/ℓ²` (infinitely smooth radiance).
    #[value(
        name = "se",
        alias = "squared_exponential",
        alias = "squared-exponential"
    )]
    SquaredExponential,
    /// Matérn ν = 3/2: `σ² (1 + √3 r) e^{−√3 r}`, `r = d/ℓ` (once differentiable).
    Matern32,
    /// Matérn ν = 5/2: `σ² (1 + √5 r + 5r²/3) e^{−√5 r}`, `r = d/ℓ` (twice differentiable).
    Matern52,
}

impl KernelKind {
    /// Every family, the default ([`KernelKind::SquaredExponential`]) first.
    pub const ALL: [KernelKind; 3] = [
        KernelKind::SquaredExponential,
        KernelKind::Matern32,
        KernelKind::Matern52,
    ];
}

/// A stationary kernel of the chordal distance with its hyperparameters.
///
/// Invariant (checked by [`Kernel::new`] and [`Kernel::validate`]):
/// `MIN_LENGTHSCALE ≤ lengthscale ≤ MAX_LENGTHSCALE`,
/// `0 < variance ≤ MAX_VARIANCE`, `0 ≤ noise ≤ MAX_VARIANCE`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Kernel {
    /// Which covariance shape.
    pub kind: KernelKind,
    /// `ℓ`, in units of chordal distance (the unit sphere's chord; `d ≤ 2`).
    pub lengthscale: f64,
    /// `σ²`, the prior variance of `f` at any direction (units of `f`²).
    pub variance: f64,
    /// `σ_n²`, observation noise variance added to the diagonal of `Q` only.
    pub noise: f64,
}

/// Bitwise identity of a kernel, for cache keys (`f64` is neither `Eq` nor `Hash`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct KernelKey {
    kind: KernelKind,
    lengthscale: u64,
    variance: u64,
    noise: u64,
}

impl Kernel {
    /// Validated kernel.
    pub fn new(
        kind: KernelKind,
        lengthscale: f64,
        variance: f64,
        noise: f64,
    ) -> Result<Kernel, BmcError> {
        let kernel = Kernel {
            kind,
            lengthscale,
            variance,
            noise,
        };
        kernel.validate()?;
        Ok(kernel)
    }

    /// Check the invariant (fields are public, so constructed values may break it).
    pub fn validate(&self) -> Result<(), BmcError> {
        if !(MIN_LENGTHSCALE..=MAX_LENGTHSCALE).contains(&self.lengthscale) {
            return Err(BmcError::invalid(
                "lengthscale",
                format!(
                    "must be in [{MIN_LENGTHSCALE}, {MAX_LENGTHSCALE}], got {}",
                    self.lengthscale
                ),
            ));
        }
        if !(self.variance > 0.0 && self.variance <= MAX_VARIANCE) {
            return Err(BmcError::invalid(
                "variance",
                format!("must be in (0, {MAX_VARIANCE:e}], got {}", self.variance),
            ));
        }
        if !(self.noise >= 0.0 && self.noise <= MAX_VARIANCE) {
            return Err(BmcError::invalid(
                "noise",
                format!("must be in [0, {MAX_VARIANCE:e}], got {}", self.noise),
            ));
        }
        Ok(())
    }

    /// Covariance `k(a, b)` of two unit directions, noise excluded.
    #[inline]
    pub fn eval(&self, a: DVec3, b: DVec3) -> f64 {
        // The chord |a − b| avoids the cancellation in a·b − 1 for nearby
        // directions (for SE, exp((a·b − 1)/ℓ²) = exp(−|a−b|²/(2ℓ²))).
        self.eval_chord((a - b).length())
    }

    /// Covariance as a function of the chordal distance `d ∈ [0, 2]`.
    #[inline]
    pub fn eval_chord(&self, d: f64) -> f64 {
        let r = d / self.lengthscale;
        self.variance
            * match self.kind {
                KernelKind::SquaredExponential => (-0.5 * r * r).exp(),
                KernelKind::Matern32 => {
                    let s = 3f64.sqrt() * r;
                    (1.0 + s) * (-s).exp()
                }
                KernelKind::Matern52 => {
                    let s = 5f64.sqrt() * r;
                    (1.0 + s + s * s / 3.0) * (-s).exp()
                }
            }
    }

    /// Covariance of two directions an angle `beta` (radians) apart; uses
    /// `d = 2 sin(β/2)`, accurate for small angles.
    #[inline]
    pub fn eval_angle(&self, beta: f64) -> f64 {
        self.eval_chord(2.0 * (0.5 * beta).sin())
    }

    /// Bitwise key for caches.
    pub fn cache_key(&self) -> KernelKey {
        KernelKey {
            kind: self.kind,
            lengthscale: self.lengthscale.to_bits(),
            variance: self.variance.to_bits(),
            noise: self.noise.to_bits(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn squared_exponential_is_a_spherical_gaussian() {
        let k = Kernel::new(KernelKind::SquaredExponential, 0.7, 2.5, 0.0).unwrap();
        let a = DVec3::new(0.3, -0.4, 0.866_025_403_784_438_6).normalize();
        let b = DVec3::new(-0.2, 0.1, 0.9).normalize();
        let sg = 2.5 * ((a.dot(b) - 1.0) / (0.7 * 0.7)).exp();
        assert!((k.eval(a, b) - sg).abs() < 1e-14);
        assert_eq!(k.eval(a, a), 2.5);
        let beta = a.dot(b).acos();
        assert!((k.eval_angle(beta) - sg).abs() < 1e-14);
    }

    #[test]
    fn matern_values_and_monotone_decay() {
        for kind in [KernelKind::Matern32, KernelKind::Matern52] {
            let k = Kernel::new(kind, 0.5, 1.5, 0.1).unwrap();
            assert_eq!(k.eval_chord(0.0), 1.5);
            let mut last = f64::INFINITY;
            for i in 0..=20 {
                let v = k.eval_chord(i as f64 * 0.1);
                assert!(v > 0.0 && v < last);
                last = v;
            }
        }
        let k = Kernel::new(KernelKind::Matern32, 2.0, 1.0, 0.0).unwrap();
        let s = 3f64.sqrt() * 0.5;
        assert!((k.eval_chord(1.0) - (1.0 + s) * (-s).exp()).abs() < 1e-15);
        let k = Kernel::new(KernelKind::Matern52, 2.0, 1.0, 0.0).unwrap();
        let s = 5f64.sqrt() * 0.5;
        assert!((k.eval_chord(1.0) - (1.0 + s + s * s / 3.0) * (-s).exp()).abs() < 1e-15);
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        let se = KernelKind::SquaredExponential;
        for (l, v, n, field) in [
            (0.0, 1.0, 0.0, "lengthscale"),
            (1e-3, 1.0, 0.0, "lengthscale"),
            (1e4, 1.0, 0.0, "lengthscale"),
            (-1.0, 1.0, 0.0, "lengthscale"),
            (f64::NAN, 1.0, 0.0, "lengthscale"),
            (f64::INFINITY, 1.0, 0.0, "lengthscale"),
            (1.0, 0.0, 0.0, "variance"),
            (1.0, f64::NAN, 0.0, "variance"),
            (1.0, 1.0, -1e-9, "noise"),
            (1.0, 1.0, f64::NAN, "noise"),
        ] {
            let err = Kernel::new(se, l, v, n).unwrap_err();
            assert_eq!(err.field(), Some(field), "{l} {v} {n}");
        }
    }

    #[test]
    fn cache_key_is_bitwise() {
        let a = Kernel::new(KernelKind::Matern52, 0.5, 1.0, 0.0).unwrap();
        let mut b = a;
        assert_eq!(a.cache_key(), b.cache_key());
        b.lengthscale = 0.5 + 1e-16 * 4.0;
        assert_ne!(a.cache_key(), b.cache_key());
        b = a;
        b.kind = KernelKind::Matern32;
        assert_ne!(a.cache_key(), b.cache_key());
    }
}
