//! Concurrent, byte-bounded cache of factorisations and quadrature weights.
//!
//! Weights `w = Q⁻¹z` depend only on the sample set, the kernel and the
//! density (docs/math.md §3), so the service computes them once per
//! configuration and reuses them at every shading point (Brouillat et al.
//! 2009). Two levels, so a new density for a known (sample set, kernel) never
//! refactorises `Q`:
//! - factorisations keyed by (`SampleSetSpec`, `KernelKey`);
//! - quadratures keyed additionally by (`DensityKey`, `PriorMean`,
//!   `KernelMeanMethod`).
//!
//! Both are moka caches weighed in bytes. Concurrent requests for one missing
//! key compute it once (moka's `try_get_with` is single flight); errors are
//! returned to every waiter and never stored, so a later request retries.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use moka::sync::Cache;
use serde::Serialize;

use crate::bmc::{
    BmcError, Density, DensityKey, Factorisation, Kernel, KernelKey, KernelMeanMethod, PriorMean,
    Quadrature,
};
use crate::sphere::{SampleSet, SampleSetSpec};

/// A sample set with the Cholesky factorisation of its kernel matrix `Q`.
#[derive(Debug)]
pub struct CachedFactorisation {
    /// The directions (local frame) the factorisation belongs to.
    pub set: SampleSet,
    /// Cholesky factor of `Q = K + σ_n² I` (plus any escalated jitter).
    pub factorisation: Factorisation,
}

impl CachedFactorisation {
    /// Approximate heap footprint (bytes), used as the cache weight.
    pub fn size_bytes(&self) -> usize {
        self.factorisation.size_bytes() + self.set.directions.len() * size_of::<glam::DVec3>()
    }
}

/// Quadrature weights and variances for one (set, kernel, density, mean,
/// kernel-mean method), with the factorisation they were solved with.
#[derive(Debug)]
pub struct CachedQuadrature {
    /// Sample set and factorisation shared with every density on them.
    pub factorised: Arc<CachedFactorisation>,
    /// Kernel means, weights, prior and posterior variance.
    pub quadrature: Quadrature,
    /// The density the weights integrate against (for the equal-weight
    /// fallback of the negative-weight guard, docs/math.md §3.6).
    pub density: Density,
}

impl CachedQuadrature {
    /// The sample directions (local frame), in weight order.
    pub fn directions(&self) -> &[glam::DVec3] {
        &self.factorised.set.directions
    }

    /// Bytes this entry keeps alive. Counts the shared factorisation too: an
    /// entry may outlive the factorisation's own cache entry, so this keeps
    /// the byte bound conservative rather than exact.
    pub fn size_bytes(&self) -> usize {
        self.quadrature.size_bytes() + self.factorised.size_bytes()
    }
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct FactorisationKey {
    set: SampleSetSpec,
    kernel: KernelKey,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct QuadratureKey {
    factorisation: FactorisationKey,
    density: DensityKey,
    prior_mean: PriorMean,
    method: KernelMeanMethod,
}

/// Counters and occupancy of a [`QuadratureCache`], for logs and `/stats`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct QuadratureCacheStats {
    /// Quadrature requests served from the cache (including waiters on an
    /// in-flight computation). Failed computations count as misses.
    pub quadrature_hits: u64,
    /// Quadrature requests that computed kernel means and weights.
    pub quadrature_misses: u64,
    /// Factorisation lookups served from the cache.
    pub factorisation_hits: u64,
    /// Factorisations computed.
    pub factorisation_misses: u64,
    /// Quadrature entries currently held.
    pub quadrature_entries: u64,
    /// Factorisation entries currently held.
    pub factorisation_entries: u64,
    /// Bytes currently held by both levels (by the weigher's accounting).
    pub bytes: u64,
    /// Configured bound on `bytes`.
    pub max_bytes: u64,
}

/// Two-level single-flight cache of factorisations and quadratures.
pub struct QuadratureCache {
    factorisations: Cache<FactorisationKey, Arc<CachedFactorisation>>,
    quadratures: Cache<QuadratureKey, Arc<CachedQuadrature>>,
    max_bytes: u64,
    factorisation_hits: AtomicU64,
    factorisation_misses: AtomicU64,
    quadrature_hits: AtomicU64,
    quadrature_misses: AtomicU64,
}

impl std::fmt::Debug for QuadratureCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QuadratureCache")
            .field("stats", &self.stats())
            .finish()
    }
}

/// moka weighs entries in `u32`; larger entries saturate (and are evicted
/// first), which only matters beyond 4 GiB.
fn weight(bytes: usize) -> u32 {
    u32::try_from(bytes).unwrap_or(u32::MAX)
}

impl QuadratureCache {
    /// Cache holding at most about `max_bytes` bytes: half for
    /// factorisations (`N²` doubles each), half for quadratures.
    pub fn new(max_bytes: u64) -> Self {
        let half = (max_bytes / 2).max(1);
        Self {
            factorisations: Cache::builder()
                .max_capacity(half)
                .weigher(|_, v: &Arc<CachedFactorisation>| weight(v.size_bytes()))
                .build(),
            quadratures: Cache::builder()
                .max_capacity(half)
                .weigher(|_, v: &Arc<CachedQuadrature>| weight(v.size_bytes()))
                .build(),
            max_bytes,
            factorisation_hits: AtomicU64::new(0),
            factorisation_misses: AtomicU64::new(0),
            quadrature_hits: AtomicU64::new(0),
            quadrature_misses: AtomicU64::new(0),
        }
    }

    /// The sample set for `spec` and the factorisation of its kernel matrix,
    /// computed at most once per key at a time. The flag is `true` when the
    /// value came from the cache (or from a concurrent request's computation).
    pub fn factorisation(
        &self,
        spec: SampleSetSpec,
        kernel: &Kernel,
    ) -> Result<(Arc<CachedFactorisation>, bool), BmcError> {
        let spec = spec.canonical();
        let key = FactorisationKey {
            set: spec,
            kernel: kernel.cache_key(),
        };
        let computed = AtomicBool::new(false);
        let value = crate::isolated::try_get_with(&self.factorisations, key, || {
            computed.store(true, Ordering::Relaxed);
            let set = SampleSet::generate(spec)?;
            let factorisation = Factorisation::new(&set, kernel)?;
            Ok::<_, BmcError>(Arc::new(CachedFactorisation { set, factorisation }))
        })
        .map_err(unshare);
        let cached = !computed.load(Ordering::Relaxed);
        count(cached, &self.factorisation_hits, &self.factorisation_misses);
        Ok((value?, cached))
    }

    /// Quadrature weights for the configuration, computed at most once per key
    /// at a time; reuses a cached factorisation of (`spec`, `kernel`). The
    /// flag is `true` when the weights came from the cache.
    pub fn quadrature(
        &self,
        spec: SampleSetSpec,
        kernel: &Kernel,
        density: &Density,
        prior_mean: PriorMean,
        method: KernelMeanMethod,
    ) -> Result<(Arc<CachedQuadrature>, bool), BmcError> {
        density.validate()?;
        let spec = spec.canonical();
        let key = QuadratureKey {
            factorisation: FactorisationKey {
                set: spec,
                kernel: kernel.cache_key(),
            },
            density: density.cache_key(),
            prior_mean,
            method,
        };
        let computed = AtomicBool::new(false);
        let value = crate::isolated::try_get_with(&self.quadratures, key, || {
            computed.store(true, Ordering::Relaxed);
            let (factorised, _) = self.factorisation(spec, kernel)?;
            let quadrature = Quadrature::new(
                &factorised.set,
                kernel,
                &factorised.factorisation,
                density,
                prior_mean,
                method,
            )?;
            Ok::<_, BmcError>(Arc::new(CachedQuadrature {
                factorised,
                quadrature,
                density: *density,
            }))
        })
        .map_err(unshare);
        let cached = !computed.load(Ordering::Relaxed);
        count(cached, &self.quadrature_hits, &self.quadrature_misses);
        Ok((value?, cached))
    }

    /// Current counters and occupancy.
    pub fn stats(&self) -> QuadratureCacheStats {
        // moka applies inserts and evictions lazily; flush so the figures
        // reflect every completed request.
        self.factorisations.run_pending_tasks();
        self.quadratures.run_pending_tasks();
        QuadratureCacheStats {
            quadrature_hits: self.quadrature_hits.load(Ordering::Relaxed),
            quadrature_misses: self.quadrature_misses.load(Ordering::Relaxed),
            factorisation_hits: self.factorisation_hits.load(Ordering::Relaxed),
            factorisation_misses: self.factorisation_misses.load(Ordering::Relaxed),
            quadrature_entries: self.quadratures.entry_count(),
            factorisation_entries: self.factorisations.entry_count(),
            bytes: self.quadratures.weighted_size() + self.factorisations.weighted_size(),
            max_bytes: self.max_bytes,
        }
    }
}

fn count(cached: bool, hits: &AtomicU64, misses: &AtomicU64) {
    let counter = if cached { hits } else { misses };
    counter.fetch_add(1, Ordering::Relaxed);
}

/// Every waiter of a failed single-flight computation receives the same
/// shared error; hand each its own copy.
fn unshare(error: Arc<BmcError>) -> BmcError {
    Arc::unwrap_or_clone(error)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::KernelKind;
    use crate::sphere::SampleSetKind;
    use std::sync::Barrier;

    fn spec(count: usize) -> SampleSetSpec {
        SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count,
            seed: 0,
        }
    }

    fn kernel(lengthscale: f64) -> Kernel {
        Kernel::new(KernelKind::SquaredExponential, lengthscale, 1.0, 1e-8).expect("valid kernel")
    }

    #[test]
    fn concurrent_requests_compute_once() {
        let cache = QuadratureCache::new(64 << 20);
        let threads = 16;
        let barrier = Barrier::new(threads);
        let results: Vec<_> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..threads)
                .map(|_| {
                    s.spawn(|| {
                        barrier.wait();
                        cache
                            .quadrature(
                                spec(48),
                                &kernel(0.5),
                                &Density::Lambert,
                                PriorMean::Gls,
                                KernelMeanMethod::Exact,
                            )
                            .expect("weights")
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("no panic"))
                .collect()
        });
        let stats = cache.stats();
        assert_eq!(stats.quadrature_misses, 1, "{stats:?}");
        assert_eq!(stats.quadrature_hits, threads as u64 - 1);
        assert_eq!(stats.factorisation_misses, 1);
        assert_eq!(results.iter().filter(|(_, cached)| !cached).count(), 1);
        assert!(results.iter().all(|(q, _)| Arc::ptr_eq(q, &results[0].0)));
    }

    #[test]
    fn new_density_reuses_the_factorisation() {
        let cache = QuadratureCache::new(64 << 20);
        let get = |density: Density| {
            cache
                .quadrature(
                    spec(32),
                    &kernel(0.6),
                    &density,
                    PriorMean::Zero,
                    KernelMeanMethod::Exact,
                )
                .expect("weights")
        };
        let (lambert, cached) = get(Density::Lambert);
        assert!(!cached);
        let (uniform, cached) = get(Density::Uniform);
        assert!(!cached);
        assert!(Arc::ptr_eq(&lambert.factorised, &uniform.factorised));
        let (again, cached) = get(Density::Lambert);
        assert!(cached && Arc::ptr_eq(&again, &lambert));
        let stats = cache.stats();
        assert_eq!(
            (stats.factorisation_misses, stats.factorisation_hits),
            (1, 1)
        );
        assert_eq!((stats.quadrature_misses, stats.quadrature_hits), (2, 1));
        assert_eq!(
            (stats.factorisation_entries, stats.quadrature_entries),
            (1, 2)
        );
        assert!(stats.bytes > 0);
    }

    #[test]
    fn errors_are_typed_and_not_cached() {
        let cache = QuadratureCache::new(64 << 20);
        let bad_density = Density::Phong {
            exponent: -1.0,
            mirror_elevation: 0.0,
        };
        let err = cache
            .quadrature(
                spec(16),
                &kernel(0.5),
                &bad_density,
                PriorMean::Zero,
                KernelMeanMethod::Exact,
            )
            .expect_err("negative exponent");
        assert_eq!(err.field(), Some("exponent"));
        let err = cache
            .quadrature(
                spec(0),
                &kernel(0.5),
                &Density::Lambert,
                PriorMean::Zero,
                KernelMeanMethod::Exact,
            )
            .expect_err("no samples");
        assert!(err.field().is_some(), "{err}");
        // The same key fails again (recomputed, not a stored error) and
        // nothing was stored.
        assert!(cache.factorisation(spec(0), &kernel(0.5)).is_err());
        let stats = cache.stats();
        assert_eq!(stats.quadrature_entries + stats.factorisation_entries, 0);
        assert_eq!(stats.factorisation_misses, 2);
    }

    #[test]
    fn byte_bound_evicts() {
        // One 64-point factorisation is ≥ 64² doubles = 32 KiB.
        let max_bytes = 200 << 10;
        let cache = QuadratureCache::new(max_bytes);
        for i in 0..20 {
            cache
                .quadrature(
                    spec(64),
                    &kernel(0.3 + 0.01 * i as f64),
                    &Density::Lambert,
                    PriorMean::Zero,
                    KernelMeanMethod::Exact,
                )
                .expect("weights");
        }
        let stats = cache.stats();
        assert!(stats.bytes <= max_bytes, "{stats:?}");
        assert!(stats.factorisation_entries < 20, "{stats:?}");
        assert_eq!(stats.quadrature_misses, 20);
    }
}
