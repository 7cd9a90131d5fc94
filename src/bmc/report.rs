//! One BMC quadrature configuration ([`QuadratureSpec`]), its stable id, and
//! the serialisable result ([`QuadratureReport`]) shared by the CLI
//! `quadrature` subcommand and the service's `POST /v1/quadratures`, so both
//! print the same fields from the same code.

use std::hash::Hasher;

use serde::{Deserialize, Serialize};

use crate::bmc::cache::{CachedQuadrature, QuadratureCache};
use crate::bmc::{BmcError, Density, Kernel, KernelMeanMethod, PriorMean};
use crate::sphere::{SampleSetKind, SampleSetSpec};

/// Everything the weights `w = Q⁻¹z` depend on (docs/math.md §3): sample set,
/// kernel, density, prior mean and how the kernel means are computed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct QuadratureSpec {
    pub sample_set: SampleSetSpec,
    pub kernel: Kernel,
    pub density: Density,
    pub prior_mean: PriorMean,
    pub kernel_mean: KernelMeanMethod,
}

impl QuadratureSpec {
    /// The same configuration with fields that do not change the weights
    /// normalised: the Fibonacci kinds ignore the seed, so it is set to 0.
    /// Two specs with equal canonical forms produce identical weights.
    pub fn canonical(self) -> QuadratureSpec {
        let mut spec = self;
        if matches!(
            spec.sample_set.kind,
            SampleSetKind::Fibonacci | SampleSetKind::FibonacciCosine
        ) {
            spec.sample_set.seed = 0;
        }
        spec
    }

    /// Stable identifier of the canonical configuration: 16 hex digits of
    /// the 64-bit FNV-1a hash of its JSON form (field order fixed by the
    /// struct, floats written in shortest round-trip form), so the id is the
    /// same across processes, machines and releases of this crate as long as
    /// the JSON field names do not change.
    pub fn id(&self) -> String {
        let json = serde_json::to_vec(&self.canonical())
            .expect("a spec of plain numbers and enums always serialises");
        let mut hasher = fnv::FnvHasher::default();
        hasher.write(&json);
        format!("{:016x}", hasher.finish())
    }

    /// The cached (or newly computed) quadrature for this configuration.
    pub fn quadrature(
        &self,
        cache: &QuadratureCache,
    ) -> Result<(std::sync::Arc<CachedQuadrature>, bool), BmcError> {
        let spec = self.canonical();
        spec.kernel.validate()?;
        cache.quadrature(
            spec.sample_set,
            &spec.kernel,
            &spec.density,
            spec.prior_mean,
            spec.kernel_mean,
        )
    }
}

/// The weights of one configuration as the CLI (`quadrature --json`) and the
/// service (`POST /v1/quadratures`) return them; field names are a public contract.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct QuadratureReport {
    /// [`QuadratureSpec::id`] of the configuration.
    pub id: String,
    /// Sample directions in the local frame (z = normal), `[x, y, z]`.
    pub directions: Vec<[f64; 3]>,
    /// `z_i = ∫ k(ω_i, ω) p(ω) dω`.
    pub kernel_means: Vec<f64>,
    /// `w` with `Î = Σ w_i Y_i`.
    pub weights: Vec<f64>,
    /// `V₀ = ∫∫ k p p`.
    pub prior_variance: f64,
    /// Posterior variance of the integral.
    pub posterior_variance: f64,
    /// Diagonal jitter the factorisation used (absolute).
    pub jitter: f64,
    /// Condition estimate of `Q`.
    pub condition_estimate: f64,
    /// `∫_H p`.
    pub density_integral: f64,
    /// Whether the weights came from the cache (no factorisation, no kernel means).
    pub cached: bool,
}

/// Looks `spec` up in `cache` (computing it on a miss) and reports it.
pub fn quadrature_report(
    spec: &QuadratureSpec,
    cache: &QuadratureCache,
) -> Result<QuadratureReport, BmcError> {
    let (entry, cached) = spec.quadrature(cache)?;
    let q = &entry.quadrature;
    Ok(QuadratureReport {
        id: spec.id(),
        directions: entry.directions().iter().map(|d| d.to_array()).collect(),
        kernel_means: q.kernel_means.clone(),
        weights: q.weights.clone(),
        prior_variance: q.prior_variance,
        posterior_variance: q.posterior_variance,
        jitter: q.jitter,
        condition_estimate: q.condition_estimate,
        density_integral: q.density_integral,
        cached,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::KernelKind;

    fn spec(kind: SampleSetKind, seed: u64, lengthscale: f64) -> QuadratureSpec {
        QuadratureSpec {
            sample_set: SampleSetSpec {
                kind,
                count: 16,
                seed,
            },
            kernel: Kernel {
                kind: KernelKind::SquaredExponential,
                lengthscale,
                variance: 1.0,
                noise: 1e-8,
            },
            density: Density::Lambert,
            prior_mean: PriorMean::Zero,
            kernel_mean: KernelMeanMethod::Exact,
        }
    }

    #[test]
    fn id_is_stable_and_ignores_only_what_does_not_change_the_weights() {
        let a = spec(SampleSetKind::Fibonacci, 0, 0.5);
        assert_eq!(a.id().len(), 16);
        assert_eq!(a.id(), spec(SampleSetKind::Fibonacci, 9, 0.5).id());
        assert_ne!(a.id(), spec(SampleSetKind::Fibonacci, 0, 0.6).id());
        assert_ne!(
            spec(SampleSetKind::Uniform, 1, 0.5).id(),
            spec(SampleSetKind::Uniform, 2, 0.5).id()
        );
    }

    #[test]
    fn report_matches_the_cached_quadrature_and_flags_the_hit() {
        let cache = QuadratureCache::new(1 << 20);
        let s = spec(SampleSetKind::FibonacciCosine, 0, 0.5);
        let first = quadrature_report(&s, &cache).expect("valid spec");
        let second = quadrature_report(&s, &cache).expect("valid spec");
        assert!(!first.cached && second.cached);
        assert_eq!(first.weights, second.weights);
        assert_eq!(first.directions.len(), 16);
        assert_eq!(first.id, s.id());
        let bad = spec(SampleSetKind::Fibonacci, 0, -1.0);
        let err = quadrature_report(&bad, &cache).expect_err("negative lengthscale");
        assert_eq!(err.field(), Some("lengthscale"));
    }
}
