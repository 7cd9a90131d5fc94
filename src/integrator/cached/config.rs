//! Options and rules of the irradiance-cache integrator, defaults written
//! once and validated once ([`CacheShadingOptions::validate`]).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::glossy::GlossyRule;
use crate::bmc::cache::QuadratureCache;
use crate::bmc::{Kernel, KernelKind, PriorMean};
use crate::cache::{Accuracy, CacheError, PixelFootprint, RecordRule, RecordRuleSpec};
use crate::render::{PathLengths, PathLimits};
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
        PixelFootprint::new(1.0, self.min_pixels, self.max_pixels)?;
        Accuracy::new(self.accuracy)
    }

    /// Placement options for records summing `paths`, seeded with `seed`.
    pub fn placement(&self, paths: PathLimits, seed: u64) -> Result<PlacementOptions, CacheError> {
        Ok(PlacementOptions {
            paths,
            accuracy: self.validate()?,
            relative_error_target: self.relative_error_target,
            occlusion_check: self.occlusion_check,
            seed,
            batch_size: self.batch_size,
            paths_per_direction: self.paths_per_direction,
        })
    }
}

/// Everything shading through the cache needs besides the cache: the
/// records' rule (part of the cache's key), the glossy rule and the
/// request's options. Build the rules once per configuration and share.
#[derive(Clone)]
pub struct CachedShading {
    pub rule: Arc<RecordRule>,
    pub glossy: Arc<GlossyRule>,
    pub options: CacheShadingOptions,
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
        options.validate()?;
        Ok(Self {
            rule: Arc::new(RecordRule::new(spec)?),
            glossy: Arc::new(GlossyRule::new(spec, glossy_bins, quadratures)?),
            options,
        })
    }

    /// The same rules with other per-request options.
    pub fn with_options(&self, options: CacheShadingOptions) -> Result<Self, CacheError> {
        options.validate()?;
        Ok(Self {
            options,
            ..self.clone()
        })
    }
}

/// Records whose rays gather from the cache are only used when paths may be
/// at least this long: a bounce through the cache counts paths of every
/// length (module docs), which matches a truncation at `max_depth` only
/// when the truncated tail (`≈ albedo^max_depth`) is negligible.
pub const AMBIENT_MIN_DEPTH: u32 = 16;
/// Lookups at a record's bounce use accuracy `min(1, factor · a)`: their
/// error is attenuated by the albedo and averaged over the record's
/// hemisphere, so coarser records serve there (as Radiance relaxes its
/// ambient accuracy at deeper bounces).
pub(crate) const AMBIENT_ACCURACY_FACTOR: f64 = 2.0;

/// Records' path limits for shading with `max_depth ≥ 2` segments from the
/// point: the indirect lengths `2..=max_depth`.
pub fn indirect_paths(max_depth: u32) -> PathLimits {
    PathLimits {
        max_depth: max_depth.max(1),
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
    /// Points decided per batch (≥ 1).
    pub batch_size: usize,
    /// Independent paths averaged per record direction (≥ 1): lowers the
    /// Monte Carlo noise of each value `L_i` without growing the `O(N²)`
    /// cost of the BMC estimate and its gradients.
    pub paths_per_direction: u32,
}
