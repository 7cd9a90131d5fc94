//! Sample sets on the hemisphere, in the local frame (z = normal).
//!
//! Every set is a deterministic function of its [`SampleSetSpec`], so a set
//! (and everything computed from it: kernel matrix, weights) can be rebuilt
//! and cached by its spec. Callers apply a per-shading-point rotation about
//! the normal with [`crate::sphere::Frame::rotated_about_normal`]; that
//! leaves `Q` and the Lambert kernel means unchanged (docs/math.md §5).

use std::f64::consts::TAU;

use glam::DVec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

use crate::bmc::BmcError;

/// Largest accepted number of directions: the kernel matrix is dense, `N²`
/// doubles (8192² · 8 B = 512 MiB) and `O(N³)` to factor.
pub const MAX_SAMPLES: usize = 8192;

/// How the directions are placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum SampleSetKind {
    /// Spherical Fibonacci, uniform area: `cos θ_i = 1 − (i + ½)/N`,
    /// `φ_i = 2π frac(i/Φ)` (Marques et al. 2013; docs/math.md §5). Seed unused.
    Fibonacci,
    /// Spherical Fibonacci, cosine-distributed: `cos θ_i = sqrt(1 − (i + ½)/N)`.
    /// Seed unused.
    #[value(alias = "fibonacci_cosine")]
    FibonacciCosine,
    /// Independent uniform directions (`pdf = 1/(2π)`).
    Uniform,
    /// Independent cosine-weighted directions (`pdf = cos θ/π`, Malley's method).
    Cosine,
    /// Jittered equal-area strata: `round(sqrt(N))` bands in `cos θ`, band `k`
    /// holding `n_k` cells (`Σ n_k = N`, sizes differing by at most one) that
    /// split the azimuth evenly; each band's height in `cos θ` is `n_k/N`, so
    /// every cell has area `2π/N`. One uniform point per cell.
    Stratified,
    /// The cells of [`Self::Stratified`] in `sin² θ` instead of `1 − cos θ`,
    /// so every cell has cosine-weighted measure `1/N`; one cosine-distributed
    /// point per cell. The equal-weight mean over it is an unbiased estimate
    /// of `∫ f cos θ/π` (stratified sampling), with a smaller variance than
    /// independent draws wherever `f` varies smoothly between cells.
    #[value(alias = "stratified_cosine")]
    StratifiedCosine,
}

/// What identifies a sample set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SampleSetSpec {
    /// Placement rule.
    pub kind: SampleSetKind,
    /// Number of directions `N`, `1 ≤ N ≤` [`MAX_SAMPLES`].
    pub count: usize,
    /// Seed of the random kinds (PCG-64); ignored by the Fibonacci kinds.
    pub seed: u64,
}

impl SampleSetSpec {
    /// The same set with the seed cleared where the kind ignores it, so keys
    /// of caches built from specs do not split one set into many (2,000
    /// Fibonacci requests differing only in `seed` once kept 2,000 fits).
    pub fn canonical(self) -> SampleSetSpec {
        match self.kind {
            SampleSetKind::Fibonacci | SampleSetKind::FibonacciCosine => {
                SampleSetSpec { seed: 0, ..self }
            }
            SampleSetKind::Uniform
            | SampleSetKind::Cosine
            | SampleSetKind::Stratified
            | SampleSetKind::StratifiedCosine => self,
        }
    }
}

/// Unit directions in the local frame, all with `z > 0`.
#[derive(Clone, Debug)]
pub struct SampleSet {
    /// The spec this set was generated from.
    pub spec: SampleSetSpec,
    /// `N` unit vectors, local frame (z = normal), `z > 0`.
    pub directions: Vec<DVec3>,
}

/// Golden ratio `Φ = (1 + √5)/2`.
const GOLDEN_RATIO: f64 = 1.618_033_988_749_895;

impl SampleSet {
    /// Deterministic set for `spec`; a typed error for `N = 0` or `N > MAX_SAMPLES`.
    pub fn generate(spec: SampleSetSpec) -> Result<SampleSet, BmcError> {
        let n = spec.count;
        if n == 0 || n > MAX_SAMPLES {
            return Err(BmcError::invalid(
                "samples",
                format!("must be between 1 and {MAX_SAMPLES}, got {n}"),
            ));
        }
        let mut rng = Pcg64::seed_from_u64(spec.seed);
        // (0, 1]: keeps random directions strictly above the horizon.
        let mut unit = move || 1.0 - rng.random::<f64>();
        let nf = n as f64;
        let directions = match spec.kind {
            SampleSetKind::Fibonacci | SampleSetKind::FibonacciCosine => (0..n)
                .map(|i| {
                    let u = 1.0 - (i as f64 + 0.5) / nf;
                    let cos_theta = if spec.kind == SampleSetKind::Fibonacci {
                        u
                    } else {
                        u.sqrt()
                    };
                    let phi = TAU * (i as f64 / GOLDEN_RATIO).fract();
                    from_spherical(cos_theta, phi)
                })
                .collect(),
            SampleSetKind::Uniform => (0..n)
                .map(|_| {
                    let cos_theta = unit();
                    from_spherical(cos_theta, TAU * unit())
                })
                .collect(),
            SampleSetKind::Cosine => (0..n)
                .map(|_| {
                    let cos_theta = unit().sqrt();
                    from_spherical(cos_theta, TAU * unit())
                })
                .collect(),
            SampleSetKind::Stratified | SampleSetKind::StratifiedCosine => {
                let bands = (nf.sqrt().round() as usize).max(1);
                let mut out = Vec::with_capacity(n);
                let mut top = 0usize;
                for k in 0..bands {
                    let bottom = (k + 1) * n / bands;
                    let cells = bottom - top;
                    for c in 0..cells {
                        // `t` (1 − cos θ, or sin² θ for the cosine kind)
                        // runs from top/N to bottom/N.
                        let t = (top as f64 + cells as f64 * (1.0 - unit())) / nf;
                        let phi = TAU * (c as f64 + 1.0 - unit()) / cells as f64;
                        let cos_theta = if spec.kind == SampleSetKind::Stratified {
                            1.0 - t
                        } else {
                            (1.0 - t).sqrt()
                        };
                        out.push(from_spherical(cos_theta.max(f64::MIN_POSITIVE), phi));
                    }
                    top = bottom;
                }
                out
            }
        };
        Ok(SampleSet { spec, directions })
    }

    /// Number of directions.
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    /// Whether the set is empty (never, for a generated set).
    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }
}

/// Unit vector with the given `cos θ` (clamped to `[0, 1]`) and azimuth.
fn from_spherical(cos_theta: f64, phi: f64) -> DVec3 {
    let c = cos_theta.clamp(0.0, 1.0);
    let s = (1.0 - c * c).sqrt();
    let (sp, cp) = phi.sin_cos();
    DVec3::new(s * cp, s * sp, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    const KINDS: [SampleSetKind; 6] = [
        SampleSetKind::Fibonacci,
        SampleSetKind::FibonacciCosine,
        SampleSetKind::Uniform,
        SampleSetKind::Cosine,
        SampleSetKind::Stratified,
        SampleSetKind::StratifiedCosine,
    ];

    fn spec(kind: SampleSetKind, count: usize, seed: u64) -> SampleSetSpec {
        SampleSetSpec { kind, count, seed }
    }

    #[test]
    fn sets_are_unit_upper_hemisphere_and_deterministic() {
        for kind in KINDS {
            for n in [1, 2, 7, 64, 300] {
                let a = SampleSet::generate(spec(kind, n, 9)).unwrap();
                assert_eq!(a.len(), n);
                for d in &a.directions {
                    assert!((d.length() - 1.0).abs() < 1e-14);
                    assert!(d.z > 0.0);
                }
                let b = SampleSet::generate(spec(kind, n, 9)).unwrap();
                assert_eq!(a.directions, b.directions);
            }
        }
        let a = SampleSet::generate(spec(SampleSetKind::Uniform, 16, 1)).unwrap();
        let b = SampleSet::generate(spec(SampleSetKind::Uniform, 16, 2)).unwrap();
        assert_ne!(a.directions, b.directions);
    }

    /// Sample means of `cos θ` and `cos² θ`: uniform-area sets give 1/2, 1/3,
    /// cosine-distributed ones 2/3, 1/2.
    #[test]
    fn moments_match_their_distribution() {
        for (kind, m1, m2, tol) in [
            (SampleSetKind::Fibonacci, 0.5, 1.0 / 3.0, 1e-4),
            (SampleSetKind::Stratified, 0.5, 1.0 / 3.0, 2e-3),
            (SampleSetKind::Uniform, 0.5, 1.0 / 3.0, 2e-2),
            (SampleSetKind::FibonacciCosine, 2.0 / 3.0, 0.5, 1e-4),
            (SampleSetKind::StratifiedCosine, 2.0 / 3.0, 0.5, 2e-3),
            (SampleSetKind::Cosine, 2.0 / 3.0, 0.5, 2e-2),
        ] {
            let set = SampleSet::generate(spec(kind, 4096, 5)).unwrap();
            let n = set.len() as f64;
            let c1 = set.directions.iter().map(|d| d.z).sum::<f64>() / n;
            let c2 = set.directions.iter().map(|d| d.z * d.z).sum::<f64>() / n;
            let mx = set.directions.iter().map(|d| d.x).sum::<f64>() / n;
            assert!((c1 - m1).abs() < tol, "{kind:?} {c1}");
            assert!((c2 - m2).abs() < tol, "{kind:?} {c2}");
            assert!(mx.abs() < 2.0 * tol, "{kind:?} {mx}");
        }
    }

    /// Both stratified kinds: band `k` of 7 holds floor((k+1)·50/7) −
    /// floor(k·50/7) points, with `1 − cos θ` (uniform area) or `sin² θ`
    /// (cosine-weighted) in its band.
    #[test]
    fn stratified_sets_have_one_point_per_equal_measure_cell() {
        let n = 50;
        let bands = 7;
        for (kind, t) in [
            (SampleSetKind::Stratified, (|z| 1.0 - z) as fn(f64) -> f64),
            (SampleSetKind::StratifiedCosine, |z| 1.0 - z * z),
        ] {
            let set = SampleSet::generate(spec(kind, n, 3)).unwrap();
            let mut i = 0;
            let mut top = 0;
            for k in 0..bands {
                let bottom = (k + 1) * n / bands;
                for _ in top..bottom {
                    let t = t(set.directions[i].z);
                    let (lo, hi) = (top as f64 / 50.0, bottom as f64 / 50.0);
                    assert!(t >= lo - 1e-12 && t <= hi + 1e-12, "{kind:?} band {k}: {t}");
                    i += 1;
                }
                top = bottom;
            }
        }
    }

    #[test]
    fn bad_counts_are_typed_errors() {
        for n in [0, MAX_SAMPLES + 1] {
            let err = SampleSet::generate(spec(SampleSetKind::Fibonacci, n, 0)).unwrap_err();
            assert_eq!(err.field(), Some("samples"));
        }
    }

    #[test]
    fn spec_serialises_in_snake_case() {
        let s = spec(SampleSetKind::FibonacciCosine, 8, 1);
        let json = serde_json::to_string(&s).unwrap();
        assert_eq!(json, r#"{"kind":"fibonacci_cosine","count":8,"seed":1}"#);
    }
}
