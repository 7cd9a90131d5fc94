//! Counters of shading through the irradiance cache.

use serde::Serialize;

/// Counters of a shading call or a request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ShadingStats {
    /// Closest-hit plus shadow rays traced.
    pub rays: u64,
    /// Diffuse points served by records.
    pub cache_hits: u64,
    /// Of those, only at the relaxed accuracy 1.
    pub relaxed_hits: u64,
    /// Diffuse points no record covered.
    pub cache_misses: u64,
    /// Records created on a miss ([`super::OnMiss::Insert`]), nested ones included.
    pub records_created: u64,
    /// Of those, created at the bounce of another record's rays ([`super::Gather::Cache`]).
    pub ambient_records: u64,
    /// Misses estimated by a path-traced sample ([`super::OnMiss::PathTrace`]).
    pub fallbacks: u64,
    /// Glossy lobes integrated by BMC.
    pub glossy_bmc: u64,
    /// Of those, estimates the negative-weight guard rejected, replaced by
    /// lobe-sampled paths (docs/math.md §3.6, §13.3).
    pub glossy_fallbacks: u64,
    /// Glossy lobes too sharp for BMC, path traced instead.
    pub glossy_path_traced: u64,
}

impl std::ops::AddAssign for ShadingStats {
    fn add_assign(&mut self, o: Self) {
        self.rays += o.rays;
        self.cache_hits += o.cache_hits;
        self.relaxed_hits += o.relaxed_hits;
        self.cache_misses += o.cache_misses;
        self.records_created += o.records_created;
        self.ambient_records += o.ambient_records;
        self.fallbacks += o.fallbacks;
        self.glossy_bmc += o.glossy_bmc;
        self.glossy_fallbacks += o.glossy_fallbacks;
        self.glossy_path_traced += o.glossy_path_traced;
    }
}
