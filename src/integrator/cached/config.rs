//! Options and rules of the irradiance-cache integrator, defaults written
//! once and validated once ([`CacheShadingOptions::validate`]).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::glossy::GlossyRule;
use super::secondary_caches::SecondaryCaches;
use crate::bmc::cache::QuadratureCache;
use crate::bmc::{Kernel, KernelKind, PriorMean};
use crate::cache::{Accuracy, CacheError, PixelFootprint, RecordRule, RecordRuleSpec};
use crate::render::{PathDepth, PathLengths, PathLimits};
use crate::sphere::{SampleSetKind, SampleSetSpec};

/// Phong exponents above this are shaded by path tracing instead of BMC.
pub const MAX_BMC_EXPONENT: f64 = 1000.0;
/// Largest accepted number of light samples per shading.
pub const MAX_LIGHT_SAMPLES: u32 = 1 << 16;
/// Largest accepted number of record levels gathering through the cache.
pub const MAX_AMBIENT_BOUNCES: u32 = 8;

/// The default rule of records and of glossy BMC: 64 spherical Fibonacci
/// directions, SE kernel `ℓ = 0.5`, jitter `10⁻⁸`, GLS constant mean.
pub fn default_rule_spec() -> RecordRuleSpec {
    RecordRuleSpec {
        samples: SampleSetSpec {
            kind: SampleSetKind::Fibonacci,
            count: 64,
            seed: 0,
        },
        kernel: Kernel {
            kind: KernelKind::SquaredExponential,
            lengthscale: 0.5,
            variance: 1.0,
            noise: 1e-8,
        },
        prior_mean: PriorMean::Gls,
    }
}

/// Per-request options of shading through the cache (the service's JSON
/// body; every field optional).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CacheShadingOptions {
    /// Ward's accuracy `a ∈ (0, 1]` (smaller: more records).
    pub accuracy: f64,
    /// Variance-driven placement target (relative standard error of a
    /// record's luminance), see [`PlacementOptions::relative_error_target`].
    pub relative_error_target: Option<f64>,
    /// Shadow ray between point and record against light leaks.
    pub occlusion_check: bool,
    /// Placement and shading on a private cache, then publish (bit-identical
    /// output whatever the thread count and the shared cache's content);
    /// otherwise use and extend the shared cache directly.
    pub reproducible: bool,
    /// Light samples per shading point for direct light (stratified).
    pub light_samples: u32,
    /// Validity radius bounds in pixel footprints (tiles only). The upper
    /// bound matters most: Ward's harmonic-mean radius grows large on open
    /// surfaces, where the records' first-order extrapolation then spans
    /// curved irradiance; 40 rather than 200 footprints cut the Cornell
    /// box's error from 2.2 % to 1.5 % for 30 % more records
    /// (docs/BENCHMARKS.md, Tabellion & Lamorlette 2004 bound radii in
    /// screen space likewise).
    pub min_pixels: f64,
    pub max_pixels: f64,
    /// Placement points decided per batch (see `placement`).
    pub batch_size: usize,
    /// Paths averaged per record direction (see [`PlacementOptions`]).
    pub paths_per_direction: u32,
    /// Levels of records whose rays gather through the cache ([`super::Gather`],
    /// Radiance's `-ab`): 0 = every record traces its rays' paths.
    pub ambient_bounces: u32,
    /// Records' rays (of tiles and radiance queries) stop at their first
    /// hit, shaded there by `paths_per_direction` light samples and the
    /// scene's secondary cache of indirect irradiance (`secondary`, built
    /// once per scene and configuration) instead of tracing paths on;
    /// excludes `ambient_bounces`.
    pub secondary_cache: bool,
    /// Records per placement point above which a tile places none and
    /// path traces its indirect light (`dense`); `None`: records everywhere.
    pub max_records_per_pixel: Option<f64>,
}

impl Default for CacheShadingOptions {
    fn default() -> Self {
        Self {
            accuracy: 0.5,
            relative_error_target: None,
            occlusion_check: false,
            reproducible: false,
            light_samples: 16,
            min_pixels: 3.0,
            max_pixels: 40.0,
            batch_size: 16,
            paths_per_direction: 1,
            ambient_bounces: 0,
            secondary_cache: false,
            max_records_per_pixel: None,
        }
    }
}

impl CacheShadingOptions {
    pub fn validate(&self) -> Result<Accuracy, CacheError> {
        if self.light_samples == 0 || self.light_samples > MAX_LIGHT_SAMPLES {
            return Err(CacheError::invalid(
                "light_samples",
                format!(
                    "must be in 1..={MAX_LIGHT_SAMPLES}, got {}",
                    self.light_samples
                ),
            ));
        }
        if self.batch_size == 0 {
            return Err(CacheError::invalid("batch_size", "must be at least 1"));
        }
        if self.paths_per_direction == 0 || self.paths_per_direction > MAX_LIGHT_SAMPLES {
            return Err(CacheError::invalid(
                "paths_per_direction",
                format!(
                    "must be in 1..={MAX_LIGHT_SAMPLES}, got {}",
                    self.paths_per_direction
                ),
            ));
        }
        if self.ambient_bounces > MAX_AMBIENT_BOUNCES {
            return Err(CacheError::invalid(
                "ambient_bounces",
                format!(
                    "must be in 0..={MAX_AMBIENT_BOUNCES}, got {}",
                    self.ambient_bounces
                ),
            ));
        }
        if self.secondary_cache && self.ambient_bounces > 0 {
            return Err(CacheError::invalid(
                "secondary_cache",
                "records gather either through the secondary cache or by ambient bounces; \
                 set ambient_bounces to 0",
            ));
        }
        if let Some(t) = self.relative_error_target
            && !(t.is_finite() && t > 0.0)
        {
            return Err(CacheError::invalid(
                "relative_error_target",
                format!("must be finite and > 0, got {t}"),
            ));
        }
        if let Some(m) = self.max_records_per_pixel
            && !(m.is_finite() && m > 0.0)
        {
            return Err(CacheError::invalid(
                "max_records_per_pixel",
                format!("must be finite and > 0, got {m}"),
            ));
        }
        PixelFootprint::new(1.0, self.min_pixels, self.max_pixels)?;
        Accuracy::new(self.accuracy)
    }
}

/// Everything shading through the cache needs besides the cache: the
/// records' rule (part of the cache's key), the glossy rule and the
/// request's options. Build the rules once per configuration and share.
#[derive(Clone)]
pub struct CachedShading {
    pub rule: Arc<RecordRule>,
    pub glossy: Arc<GlossyRule>,
    /// Validated when this value is built, never again per shading point.
    pub options: CacheShadingOptions,
    /// `options.accuracy`, checked.
    pub(super) accuracy: Accuracy,
    /// Secondary caches for these rules, built on first use and shared by
    /// clones ([`SecondaryCaches`]).
    pub secondary: SecondaryCaches,
}

impl CachedShading {
    /// Rules for `spec` (records and glossy BMC share sample set and kernel)
    /// with `glossy_bins` `θ_r` nodes; validates `options`.
    pub fn new(
        spec: RecordRuleSpec,
        glossy_bins: usize,
        quadratures: Arc<QuadratureCache>,
        options: CacheShadingOptions,
    ) -> Result<Self, CacheError> {
        Self::with_glossy_spec(spec, spec, glossy_bins, quadratures, options)
    }

    /// Rules for records by `spec` and for glossy BMC by `glossy`.
    pub fn with_glossy_spec(
        spec: RecordRuleSpec,
        glossy: RecordRuleSpec,
        glossy_bins: usize,
        quadratures: Arc<QuadratureCache>,
        options: CacheShadingOptions,
    ) -> Result<Self, CacheError> {
        let accuracy = options.validate()?;
        Ok(Self {
            rule: Arc::new(RecordRule::new(spec)?),
            glossy: Arc::new(GlossyRule::new(glossy, glossy_bins, quadratures)?),
            options,
            accuracy,
            secondary: SecondaryCaches::default(),
        })
    }

    /// Ward's accuracy of lookups, checked.
    pub fn accuracy(&self) -> Accuracy {
        self.accuracy
    }

    /// Placement options for records summing `paths`, seeded with `seed`.
    pub fn placement(&self, paths: PathLimits, seed: u64) -> PlacementOptions {
        let o = &self.options;
        PlacementOptions {
            paths,
            accuracy: self.accuracy,
            relative_error_target: o.relative_error_target,
            occlusion_check: o.occlusion_check,
            seed,
            batch_size: o.batch_size,
            paths_per_direction: o.paths_per_direction,
        }
    }
}

/// Records whose rays gather from the cache are only used when paths may be
/// at least this long: a bounce through the cache counts paths of every
/// length (module docs), which matches a truncation at `max_depth` only
/// when the truncated tail (`≈ albedo^max_depth`) is negligible.
pub const AMBIENT_MIN_DEPTH: PathDepth = PathDepth::constant(16);
/// Lookups at a record's bounce use accuracy `min(1, factor · a)`: their
/// error is attenuated by the albedo and averaged over the record's
/// hemisphere, so coarser records serve there (as Radiance relaxes its
/// ambient accuracy at deeper bounces).
pub(crate) const AMBIENT_ACCURACY_FACTOR: f64 = 2.0;

/// Records' path limits for shading a point with paths of up to
/// `from_point` segments counted from the point itself (a camera ray's
/// depth [`PathDepth::after_first_segment`]): the indirect lengths
/// `2..=from_point`.
pub fn indirect_paths(from_point: PathDepth) -> PathLimits {
    PathLimits {
        max_depth: from_point,
        lengths: PathLengths::Indirect,
    }
}

/// How records are placed and used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacementOptions {
    /// Which paths the records' rays sum: [`crate::render::PathLengths::Indirect`]
    /// when direct light is added separately by light sampling, `All` otherwise.
    pub paths: PathLimits,
    /// Ward's accuracy for deciding coverage and for shading.
    pub accuracy: Accuracy,
    /// Variance-driven placement: also create a record where the cache does
    /// give a value but its relative standard error of luminance,
    /// `sqrt(Σ_c y_c² V_c)/Y(E)` (Rec. 709 weights `y_c`, channels taken as
    /// independent), exceeds this.
    pub relative_error_target: Option<f64>,
    /// Shadow-ray test between point and record (module docs).
    pub occlusion_check: bool,
    /// Seed of every random stream of the request.
    pub seed: u64,
    /// Points decided per batch (≥ 1; checked by
    /// [`CacheShadingOptions::validate`], assumed by placement).
    pub batch_size: usize,
    /// Independent paths averaged per record direction (≥ 1): lowers the
    /// Monte Carlo noise of each value `L_i` without growing the `O(N²)`
    /// cost of the BMC estimate and its gradients.
    pub paths_per_direction: u32,
}
