//! The integrator a request or the command line names, as data: which
//! method (`method`) and that method's own knobs, one spec type per method
//! ([`PathSpec`], [`CachedSpec`]). The wire form is one flat object,
//! `{"method": "cache", "samples": 256, …}`, `method` defaulting to `cache`;
//! a knob of another method is refused, naming it.

use std::fmt;

use serde::de::{self, MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};
use utoipa::ToSchema;

use super::cached::CachedSpec;
use super::method::Method;
use super::resolved::Integrator;
use crate::cache::CacheError;

/// The path tracer's knobs: none beyond the request's own (samples per
/// pixel, `max_depth`, seed), so any other field is refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {}

/// An integrator and its knobs, as a request's `estimator` or the command
/// line names it. `method`: `cache` (default; `bmc` is an alias), the
/// Bayesian irradiance cache — light sampling for direct light, `(k_d/π)·E`
/// interpolated from BMC records for diffuse indirect light, BMC with the
/// Phong density for glossy reflection; or `path`, path tracing with NEE
/// and MIS, the unbiased reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "method", rename_all = "lowercase")]
pub enum IntegratorSpec {
    Path(PathSpec),
    Cache(CachedSpec),
}

impl Default for IntegratorSpec {
    fn default() -> Self {
        IntegratorSpec::Cache(CachedSpec::default())
    }
}

impl IntegratorSpec {
    pub fn method(&self) -> Method {
        match self {
            IntegratorSpec::Path(_) => Method::Path,
            IntegratorSpec::Cache(_) => Method::Cache,
        }
    }

    /// `method` with `knobs` (the command line's flattened cache knobs),
    /// which must be unset unless `method` is the cache integrator.
    pub fn with_knobs(method: Method, knobs: CachedSpec) -> Result<Self, CacheError> {
        match method {
            Method::Cache => Ok(IntegratorSpec::Cache(knobs)),
            Method::Path if knobs == CachedSpec::default() => Ok(IntegratorSpec::Path(PathSpec {})),
            Method::Path => Err(CacheError::invalid(
                "method",
                "the cache integrator's options need the cache method",
            )),
        }
    }

    /// The cache integrator's knobs, if this names it.
    pub fn cached(&self) -> Option<&CachedSpec> {
        match self {
            IntegratorSpec::Cache(spec) => Some(spec),
            IntegratorSpec::Path(_) => None,
        }
    }

    /// `self` with `base`'s knobs (a preset's) under those `self` leaves
    /// unset, when both name the same method; otherwise `self`.
    pub fn over(self, base: IntegratorSpec) -> IntegratorSpec {
        match (self, base) {
            (IntegratorSpec::Cache(spec), IntegratorSpec::Cache(base)) => {
                IntegratorSpec::Cache(spec.over(base))
            }
            (spec, _) => spec,
        }
    }

    /// The defaults filled in and every knob checked, once (errors name the
    /// field); nothing downstream checks again.
    pub fn resolve(&self) -> Result<Integrator, CacheError> {
        Ok(match self {
            IntegratorSpec::Path(_) => Integrator::Path,
            IntegratorSpec::Cache(spec) => Integrator::Cache(spec.resolve()?),
        })
    }
}

/// The flat wire form: `method` (tracked by `serde_path_to_error` as
/// `….method`) picks the spec the other fields deserialise into.
impl<'de> Deserialize<'de> for IntegratorSpec {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Fields;
        impl<'de> Visitor<'de> for Fields {
            type Value = IntegratorSpec;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an object with an optional `method` and that method's knobs")
            }

            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut method = None;
                let mut knobs = serde_json::Map::new();
                while let Some(key) = map.next_key::<String>()? {
                    if key == "method" {
                        if method.is_some() {
                            return Err(de::Error::duplicate_field("method"));
                        }
                        method = Some(map.next_value::<Method>()?);
                    } else {
                        let value = map.next_value::<serde_json::Value>()?;
                        knobs.insert(key, value);
                    }
                }
                let knobs = serde_json::Value::Object(knobs);
                let spec = match method.unwrap_or_default() {
                    Method::Path => {
                        serde_path_to_error::deserialize(knobs).map(IntegratorSpec::Path)
                    }
                    Method::Cache => {
                        serde_path_to_error::deserialize(knobs).map(IntegratorSpec::Cache)
                    }
                };
                // The knob's own name leads the message, as the outer path
                // ends at the document.
                spec.map_err(|err| match err.path().to_string().as_str() {
                    "." => de::Error::custom(err.into_inner()),
                    path => de::Error::custom(format!("{path}: {}", err.into_inner())),
                })
            }
        }
        deserializer.deserialize_map(Fields)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<IntegratorSpec, String> {
        let mut de = serde_json::Deserializer::from_str(text);
        serde_path_to_error::deserialize(&mut de).map_err(|e| format!("{} | {}", e.path(), e))
    }

    #[test]
    fn method_picks_the_spec_and_defaults_to_cache() {
        assert_eq!(parse("{}").unwrap(), IntegratorSpec::default());
        assert_eq!(
            parse(r#"{"method": "path"}"#).unwrap(),
            IntegratorSpec::Path(PathSpec {})
        );
        let cache = parse(r#"{"samples": 16, "method": "cache"}"#).unwrap();
        assert_eq!(cache.cached().and_then(|c| c.samples), Some(16));
        assert_eq!(cache.method(), Method::Cache);
        // `bmc` is a point estimator's name, never a tile integrator's.
        let err = parse(r#"{"method": "bmc"}"#).unwrap_err();
        assert!(err.contains("expected `path` or `cache`"), "{err}");
    }

    #[test]
    fn errors_name_the_field() {
        let err = parse(r#"{"method": "magic"}"#).unwrap_err();
        assert!(err.starts_with("method |"), "{err}");
        let err = parse(r#"{"method": "path", "samples": 4}"#).unwrap_err();
        assert!(err.contains("unknown field `samples`"), "{err}");
        let err = parse(r#"{"samples": "many"}"#).unwrap_err();
        assert!(err.contains("samples: invalid type"), "{err}");
        assert!(parse(r#"{"method": "path", "method": "cache"}"#).is_err());
    }

    #[test]
    fn the_wire_form_round_trips() {
        for text in [
            r#"{"method":"path"}"#,
            r#"{"method":"cache"}"#,
            r#"{"method":"cache","samples":256,"reproducible":true}"#,
        ] {
            let spec = parse(text).unwrap();
            assert_eq!(serde_json::to_string(&spec).unwrap(), text);
        }
    }

    #[test]
    fn knobs_override_a_base_of_the_same_method_only() {
        let base = IntegratorSpec::Cache(CachedSpec {
            samples: Some(256),
            accuracy: Some(0.4),
            ..CachedSpec::default()
        });
        let spec = IntegratorSpec::Cache(CachedSpec {
            samples: Some(16),
            ..CachedSpec::default()
        });
        let merged = spec.over(base);
        let merged = merged.cached().unwrap();
        assert_eq!((merged.samples, merged.accuracy), (Some(16), Some(0.4)));
        let path = IntegratorSpec::Path(PathSpec {});
        assert_eq!(path.over(base), path);
    }
}
