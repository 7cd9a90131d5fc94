//! The cache integrator's knobs, described once: [`CachedSpec`] is the
//! request document of the service (`"estimator": {"method": "cache", …}`),
//! the command line's arguments (`render --method cache`, clap flatten) and
//! the OpenAPI schema, each knob's doc comment stating its meaning, bounds
//! and default. [`CachedSpec::resolve`] fills the defaults (written once,
//! in [`super::default_rule_spec`], [`CacheShadingOptions::default`] and
//! [`DEFAULT_GLOSSY_BINS`]) and checks every field, once; nothing
//! downstream checks again. A test holds the docs to the resolved defaults.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::config::{CacheShadingOptions, CachedShading, default_rule_spec};
use super::glossy::MAX_GLOSSY_BINS;
use crate::bmc::cache::QuadratureCache;
use crate::bmc::{KernelKey, PriorMean};
use crate::cache::{Accuracy, CacheError, RecordRuleSpec};
use crate::render::PathDepth;
use crate::sphere::SampleSetSpec;

/// `θ_r` nodes of the glossy rule when none are named.
pub const DEFAULT_GLOSSY_BINS: usize = 16;
/// Directions per record when none are named.
pub const DEFAULT_RECORD_SAMPLES: usize = 64;

/// The irradiance-cache integrator as a request or the command line names
/// it: every knob optional, `None` taking the default its doc states.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct CachedSpec {
    /// Directions per record (spherical Fibonacci), 1..=`sphere::MAX_SAMPLES`
    /// (the service: at most `limits.max_samples`); default 64.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub samples: Option<usize>,
    /// Directions of each glossy BMC estimate (one per camera ray on a
    /// glossy surface, so it sets the glossy shading cost), bounded as
    /// `samples`; default `samples`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub glossy_samples: Option<usize>,
    /// SE kernel lengthscale of the records' and glossy BMC's GP prior
    /// (chordal units), > 0; default 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub lengthscale: Option<f64>,
    /// Noise variance σ_n² relative to σ² = 1, ≥ 0; default 1e-8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub noise: Option<f64>,
    /// Paths traced per record direction and averaged (with
    /// `secondary_cache`, light samples at each direction's first hit),
    /// 1..=65536; default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub paths_per_direction: Option<u32>,
    /// Levels of records whose rays gather through the cache
    /// (Radiance-style ambient bounces: direct light plus cached indirect
    /// irradiance at each ray's hit), 0..=8; 0 = records trace full paths.
    /// Default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub ambient_bounces: Option<u32>,
    /// Records' rays (of tiles and radiance queries) stop at their first
    /// hit, shaded there by light samples and the scene's secondary cache
    /// of indirect irradiance (built once per scene and configuration, by
    /// the first request that needs it) instead of tracing paths on; used
    /// when `max_depth` leaves at least 16 segments after the shading
    /// point; excludes `ambient_bounces`. Default false.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long, num_args = 0..=1, default_missing_value = "true")]
    pub secondary_cache: Option<bool>,
    /// Ward's accuracy a ∈ (0, 1]; smaller places more records. Default 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub accuracy: Option<f64>,
    /// Also place a record where the interpolated relative standard error
    /// of luminance exceeds this (variance-driven placement), finite and
    /// > 0; default off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub relative_error_target: Option<f64>,
    /// Shadow ray between a point and each record it uses (no light leaks
    /// through thin walls). Default false.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long, num_args = 0..=1, default_missing_value = "true")]
    pub occlusion_check: Option<bool>,
    /// Light samples per shading point for direct light, 1..=65536; default 16.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub light_samples: Option<u32>,
    /// Bit-identical output whatever the thread count and whatever ran
    /// before: records are placed in a private cache for each tile, then
    /// published to the shared one. Default false.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long, num_args = 0..=1, default_missing_value = "true")]
    pub reproducible: Option<bool>,
    /// Use the scene's shared cache; false computes every record for this
    /// request alone and keeps none. Default true.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub cache: Option<bool>,
    /// Smallest record radius, in pixel footprints at the record (tiles),
    /// > 0; default 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub min_pixels: Option<f64>,
    /// Largest record radius, in pixel footprints at the record (tiles),
    /// ≥ `min_pixels`; default 40.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub max_pixels: Option<f64>,
    /// Records per camera-visible diffuse pixel of a tile above which the
    /// tile places none: its camera samples' indirect light is then path
    /// traced, two paths each, and their direct light takes twice
    /// `light_samples` (decided by a cheap probe of the placement; tiles
    /// only), finite and > 0; default off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub max_records_per_pixel: Option<f64>,
    /// Mirror-angle (`θ_r`) nodes of the glossy BMC rule, 2..=1024; default 16.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub glossy_bins: Option<usize>,
}

/// A checked configuration of the cache integrator.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CachedConfig {
    /// The records' (and glossy BMC's) rule.
    pub rule: RecordRuleSpec,
    pub options: CacheShadingOptions,
    pub glossy_bins: usize,
    /// Directions of each glossy BMC estimate.
    pub glossy_samples: usize,
    /// Whether requests read and extend the scene's shared cache.
    pub shared: bool,
    /// `options.accuracy`, checked with the rest of `options` by [`CachedSpec::resolve`].
    pub(super) accuracy: Accuracy,
}

/// What the values of a cache's records depend on, and nothing else: the
/// key under which records of one scene version are shared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RecordsKey {
    samples: SampleSetSpec,
    kernel: KernelKey,
    prior_mean: PriorMean,
    paths_per_direction: u32,
    ambient_bounces: u32,
    secondary_cache: bool,
    /// Path segments counted from the camera or viewer.
    max_depth: PathDepth,
    glossy_bins: usize,
    glossy_samples: usize,
}

impl RecordsKey {
    /// Path segments counted from the camera or viewer.
    pub fn max_depth(&self) -> PathDepth {
        self.max_depth
    }
}

impl CachedSpec {
    /// `self` with `base`'s knobs (a preset's) where `self` names none. The
    /// secondary cache and ambient bounces are two ways for records' rays to
    /// go on, and exclude each other: ambient bounces that `self` asks for
    /// also turn off `base`'s secondary cache.
    pub fn over(self, base: CachedSpec) -> CachedSpec {
        let ambient = self.ambient_bounces.is_some_and(|b| b > 0);
        CachedSpec {
            samples: self.samples.or(base.samples),
            glossy_samples: self.glossy_samples.or(base.glossy_samples),
            lengthscale: self.lengthscale.or(base.lengthscale),
            noise: self.noise.or(base.noise),
            paths_per_direction: self.paths_per_direction.or(base.paths_per_direction),
            ambient_bounces: self.ambient_bounces.or(base.ambient_bounces),
            secondary_cache: self
                .secondary_cache
                .or(base.secondary_cache.filter(|_| !ambient)),
            accuracy: self.accuracy.or(base.accuracy),
            relative_error_target: self.relative_error_target.or(base.relative_error_target),
            occlusion_check: self.occlusion_check.or(base.occlusion_check),
            light_samples: self.light_samples.or(base.light_samples),
            reproducible: self.reproducible.or(base.reproducible),
            cache: self.cache.or(base.cache),
            min_pixels: self.min_pixels.or(base.min_pixels),
            max_pixels: self.max_pixels.or(base.max_pixels),
            max_records_per_pixel: self.max_records_per_pixel.or(base.max_records_per_pixel),
            glossy_bins: self.glossy_bins.or(base.glossy_bins),
        }
    }

    /// The defaults filled in and every value checked (errors name the field).
    pub fn resolve(&self) -> Result<CachedConfig, CacheError> {
        let mut rule = default_rule_spec();
        rule.samples.count = self.samples.unwrap_or(DEFAULT_RECORD_SAMPLES);
        if let Some(lengthscale) = self.lengthscale {
            rule.kernel.lengthscale = lengthscale;
        }
        if let Some(noise) = self.noise {
            rule.kernel.noise = noise;
        }
        rule.kernel.validate()?;
        let glossy_samples = self.glossy_samples.unwrap_or(rule.samples.count);
        for (field, count) in [
            ("samples", rule.samples.count),
            ("glossy_samples", glossy_samples),
        ] {
            if !(1..=crate::sphere::MAX_SAMPLES).contains(&count) {
                return Err(CacheError::invalid(
                    field,
                    format!("must be in 1..={}, got {count}", crate::sphere::MAX_SAMPLES),
                ));
            }
        }
        let d = CacheShadingOptions::default();
        let options = CacheShadingOptions {
            accuracy: self.accuracy.unwrap_or(d.accuracy),
            relative_error_target: self.relative_error_target.or(d.relative_error_target),
            occlusion_check: self.occlusion_check.unwrap_or(d.occlusion_check),
            reproducible: self.reproducible.unwrap_or(d.reproducible),
            light_samples: self.light_samples.unwrap_or(d.light_samples),
            paths_per_direction: self.paths_per_direction.unwrap_or(d.paths_per_direction),
            ambient_bounces: self.ambient_bounces.unwrap_or(d.ambient_bounces),
            secondary_cache: self.secondary_cache.unwrap_or(d.secondary_cache),
            min_pixels: self.min_pixels.unwrap_or(d.min_pixels),
            max_pixels: self.max_pixels.unwrap_or(d.max_pixels),
            max_records_per_pixel: self.max_records_per_pixel.or(d.max_records_per_pixel),
            ..d
        };
        let accuracy = options.validate()?;
        let glossy_bins = self.glossy_bins.unwrap_or(DEFAULT_GLOSSY_BINS);
        if !(2..=MAX_GLOSSY_BINS).contains(&glossy_bins) {
            return Err(CacheError::invalid(
                "glossy_bins",
                format!("must be in 2..={MAX_GLOSSY_BINS}, got {glossy_bins}"),
            ));
        }
        Ok(CachedConfig {
            rule,
            options,
            glossy_bins,
            glossy_samples,
            shared: self.cache.unwrap_or(true),
            accuracy,
        })
    }
}

impl CachedConfig {
    /// Paths one record may trace: its directions times the paths per
    /// direction, once more per ambient level that re-gathers them. Records
    /// that ambient levels place at secondary hits are not counted: how many
    /// there are depends on what the cache already holds.
    pub fn paths_per_record(&self) -> u64 {
        self.rule.samples.count as u64
            * u64::from(self.options.paths_per_direction)
            * (1 + u64::from(self.options.ambient_bounces))
    }

    /// Whether a tile's output depends only on the scene's content and the
    /// request: placed on a private cache, and not kept from the shared one.
    pub fn reproducible(&self) -> bool {
        self.options.reproducible && self.shared
    }

    /// The key of the records this configuration computes for paths of up
    /// to `max_depth` segments from the camera or viewer.
    pub fn records_key(&self, max_depth: PathDepth) -> RecordsKey {
        RecordsKey {
            samples: self.rule.samples.canonical(),
            kernel: self.rule.kernel.cache_key(),
            prior_mean: self.rule.prior_mean,
            paths_per_direction: self.options.paths_per_direction,
            ambient_bounces: self.options.ambient_bounces,
            secondary_cache: self.options.secondary_cache,
            max_depth,
            glossy_bins: self.glossy_bins,
            glossy_samples: self.glossy_samples,
        }
    }

    /// The same as JSON, for people reading cache statistics.
    pub fn describe(&self, max_depth: PathDepth) -> serde_json::Value {
        serde_json::json!({
            "rule": self.rule,
            "paths_per_direction": self.options.paths_per_direction,
            "ambient_bounces": self.options.ambient_bounces,
            "secondary_cache": self.options.secondary_cache,
            "max_depth": max_depth,
            "glossy_bins": self.glossy_bins,
            "glossy_samples": self.glossy_samples,
        })
    }

    /// `rules` (built for a configuration with the same records key) with
    /// this configuration's per-request options, already checked.
    pub fn apply_to(&self, rules: &CachedShading) -> CachedShading {
        CachedShading {
            options: self.options,
            accuracy: self.accuracy,
            ..rules.clone()
        }
    }

    /// The rules (factorised once per configuration) with these options.
    pub fn shading(&self, quadratures: Arc<QuadratureCache>) -> Result<CachedShading, CacheError> {
        let mut glossy = self.rule;
        glossy.samples.count = self.glossy_samples;
        CachedShading::with_glossy_spec(
            self.rule,
            glossy,
            self.glossy_bins,
            quadratures,
            self.options,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use utoipa::PartialSchema;
    use utoipa::openapi::schema::{Schema, SchemaType, Type};
    use utoipa::openapi::{RefOr, schema::Object};

    /// Every knob set to the value resolving an empty spec gives it.
    fn defaults() -> serde_json::Value {
        let c = CachedSpec::default()
            .resolve()
            .expect("the defaults are valid");
        let o = &c.options;
        serde_json::json!({
            "samples": c.rule.samples.count,
            "glossy_samples": "`samples`",
            "lengthscale": c.rule.kernel.lengthscale,
            "noise": c.rule.kernel.noise,
            "paths_per_direction": o.paths_per_direction,
            "ambient_bounces": o.ambient_bounces,
            "secondary_cache": o.secondary_cache,
            "accuracy": o.accuracy,
            "relative_error_target": o.relative_error_target.map_or("off".into(), |t| t.to_string()),
            "occlusion_check": o.occlusion_check,
            "light_samples": o.light_samples,
            "reproducible": o.reproducible,
            "cache": c.shared,
            "min_pixels": o.min_pixels,
            "max_pixels": o.max_pixels,
            "max_records_per_pixel": o.max_records_per_pixel.map_or("off".into(), |m| m.to_string()),
            "glossy_bins": c.glossy_bins,
        })
    }

    fn properties() -> Object {
        match CachedSpec::schema() {
            RefOr::T(Schema::Object(object)) => object,
            _ => panic!("CachedSpec is not an object schema"),
        }
    }

    #[test]
    fn every_knob_documents_the_default_it_resolves_to() {
        let defaults = defaults();
        let defaults = defaults.as_object().expect("an object");
        let schema = properties();
        assert_eq!(
            schema.properties.len(),
            defaults.len(),
            "a knob without a default here"
        );
        for (name, value) in defaults {
            let Some(RefOr::T(Schema::Object(property))) = schema.properties.get(name) else {
                panic!("{name} is not in the schema");
            };
            let text = match value {
                serde_json::Value::String(s) => s.clone(),
                v => v.to_string(),
            };
            let doc = property.description.clone().unwrap_or_default();
            let doc = doc.replace('\n', " ").to_lowercase();
            assert!(
                doc.contains(&format!("default {text}"))
                    || doc.contains(&format!("default {}", text.trim_end_matches(".0"))),
                "{name}: the docs ({doc:?}) do not say its default is {text}"
            );
            assert!(
                !matches!(property.schema_type, SchemaType::Type(Type::Object)),
                "{name} is a flat knob"
            );
        }
    }

    #[test]
    fn the_wire_form_round_trips_and_refuses_unknown_knobs() {
        let spec = CachedSpec {
            samples: Some(256),
            secondary_cache: Some(true),
            min_pixels: Some(8.0),
            ..CachedSpec::default()
        };
        let text = serde_json::to_string(&spec).expect("serialises");
        assert_eq!(
            text,
            r#"{"samples":256,"secondary_cache":true,"min_pixels":8.0}"#
        );
        assert_eq!(
            serde_json::from_str::<CachedSpec>(&text).expect("parses"),
            spec
        );
        let err = serde_json::from_str::<CachedSpec>(r#"{"sample": 4}"#).unwrap_err();
        assert!(err.to_string().contains("unknown field `sample`"), "{err}");
    }

    #[test]
    fn every_field_is_checked_by_resolve() {
        let field = |spec: CachedSpec| match spec.resolve() {
            Err(err) => err.field().map(str::to_owned).unwrap_or_default(),
            Ok(config) => panic!("{spec:?} resolved to {config:?}"),
        };
        let d = CachedSpec::default;
        assert_eq!(
            field(CachedSpec {
                samples: Some(0),
                ..d()
            }),
            "samples"
        );
        assert_eq!(
            field(CachedSpec {
                glossy_samples: Some(0),
                ..d()
            }),
            "glossy_samples"
        );
        assert_eq!(
            field(CachedSpec {
                relative_error_target: Some(-1.0),
                ..d()
            }),
            "relative_error_target"
        );
        assert_eq!(
            field(CachedSpec {
                relative_error_target: Some(f64::NAN),
                ..d()
            }),
            "relative_error_target"
        );
        assert_eq!(
            field(CachedSpec {
                light_samples: Some(0),
                ..d()
            }),
            "light_samples"
        );
        assert_eq!(
            field(CachedSpec {
                paths_per_direction: Some(0),
                ..d()
            }),
            "paths_per_direction"
        );
        assert_eq!(
            field(CachedSpec {
                ambient_bounces: Some(9),
                ..d()
            }),
            "ambient_bounces"
        );
        assert_eq!(
            field(CachedSpec {
                glossy_bins: Some(1),
                ..d()
            }),
            "glossy_bins"
        );
        assert_eq!(
            field(CachedSpec {
                accuracy: Some(0.0),
                ..d()
            }),
            "accuracy"
        );
    }

    /// A request's ambient bounces over a preset whose records read the
    /// secondary cache: the request's way wins and resolves; naming both
    /// is still refused.
    #[test]
    fn asked_for_ambient_bounces_turn_off_a_presets_secondary_cache() {
        let preset = CachedSpec {
            secondary_cache: Some(true),
            samples: Some(256),
            ..CachedSpec::default()
        };
        let ambient = |bounces| CachedSpec {
            ambient_bounces: Some(bounces),
            ..CachedSpec::default()
        };
        let merged = ambient(2).over(preset);
        assert_eq!(merged.secondary_cache, None);
        assert_eq!(merged.samples, Some(256));
        assert!(merged.resolve().is_ok());
        assert_eq!(ambient(0).over(preset).secondary_cache, Some(true));
        let both = CachedSpec {
            secondary_cache: Some(true),
            ..ambient(2)
        };
        assert!(both.over(preset).resolve().is_err());
    }
}
