//! Service configuration: `config/default.toml`, an optional file, environment
//! variables and command-line flags, merged in that order.
//!
//! The defaults are compiled into the binary (`config/default.toml` is the
//! single source of every default and documents each key), so `serve` works
//! from any working directory. Layers, later ones winning:
//!
//! 1. `config/default.toml` (embedded);
//! 2. `--config FILE`: any subset of the same sections and keys;
//! 3. environment variables `BMC_<SECTION>__<KEY>=value` (case-insensitive,
//!    double underscore between section and key), e.g. `BMC_LIMITS__MAX_POINTS=4096`.
//!    The value is parsed as the type of the default it replaces (integer or
//!    string). Variables starting with `BMC_` without a `__` are not ours and are ignored;
//!    a `BMC_X__Y` naming an unknown section or key is an error;
//! 4. `--bind ADDR`.
//!
//! Unknown sections or keys in any layer are errors, so a misspelt key is never
//! silently ignored. [`Config::validate`] then rejects values the service cannot run with.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use toml::{Table, Value};

/// The embedded default configuration (`config/default.toml`).
pub const DEFAULT_TOML: &str = include_str!("../../config/default.toml");

/// One irradiance-cache record may take at most this fraction (its inverse)
/// of `limits.max_paths_per_request` (see [`Limits::check_record_work`]).
pub const RECORD_SHARE: u64 = 64;

/// Prefix of environment variables that override configuration keys.
pub const ENV_PREFIX: &str = "BMC_";

/// Why a configuration could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config file {path} is not valid TOML: {source}")]
    Parse {
        path: PathBuf,
        source: toml::de::Error,
    },
    #[error("{origin}: unknown config key `{key}`")]
    UnknownKey { origin: String, key: String },
    #[error("{origin}: `{key}` expects {expected}, got {value:?}")]
    BadValue {
        origin: String,
        key: String,
        expected: &'static str,
        value: String,
    },
    #[error("invalid configuration: {0}")]
    Shape(#[from] toml::de::Error),
    #[error("invalid configuration: `{field}` {reason}")]
    Invalid { field: &'static str, reason: String },
}

/// The whole service configuration; see `config/default.toml` for each key's meaning.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub server: ServerConfig,
    pub cache: CacheConfig,
    pub limits: Limits,
    pub scenes: ScenesConfig,
    pub cluster: ClusterConfig,
}

/// Sharing with other replicas (`service::shared_store`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterConfig {
    /// Redis shared by the replicas (`redis://host:port/db`); empty = this
    /// process alone.
    pub redis_url: String,
    /// Prefix of every Redis key of this service.
    pub redis_prefix: String,
    /// Entries kept in the shared stream of tile parts; older ones are
    /// trimmed (approximately, as Redis's `MAXLEN ~` does).
    pub shared_parts: u64,
    /// A secret the replicas share: what one sends through Redis carries a
    /// keyed BLAKE3 hash of it, and what lacks a valid one is not taken.
    /// Empty = whatever Redis holds is trusted (warned at startup).
    pub secret: String,
}

/// Listener and thread counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServerConfig {
    /// Address to listen on (port 0 = any free port).
    pub bind: SocketAddr,
    /// Async runtime threads (0 = number of cores).
    pub runtime_threads: usize,
    /// CPU pool threads (0 = number of cores).
    pub worker_threads: usize,
    /// Seconds a connection may take to send a request head, and may stay
    /// idle between requests, before it is closed.
    pub header_read_timeout_secs: u64,
    /// Open connections at most; further ones are closed at once.
    pub max_connections: usize,
    /// Seconds in-flight requests get to finish after SIGTERM/SIGINT.
    pub shutdown_grace_secs: u64,
    /// Bearer token that mutating routes require (`Authorization: Bearer
    /// <token>`); empty = none (the default, meant for loopback binds).
    pub auth_token: String,
    /// Web origins (`scheme://host[:port]`, comma-separated) whose pages may
    /// send requests that change state; empty = none. Requests from other
    /// origins (a browser's `Origin` header naming another site) are refused
    /// with 403 whatever `auth_token` is, as browsers send simple cross-site
    /// POSTs without asking first.
    pub allowed_origins: String,
}

/// Byte budgets of the caches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CacheConfig {
    /// Bytes held by the BMC factorisation and weight cache.
    pub factorisation_bytes: u64,
    /// Bytes held by the irradiance-cache records of all scenes together.
    pub irradiance_bytes: u64,
    /// Bytes held by reproducible tiles' records and rendered passes
    /// (`GET …/tiles/…`), so passes and AOVs of a tile reuse them.
    pub tile_bytes: u64,
    /// Directory of what survives a restart (`tiles.log`, see
    /// `service::tile_store`), relative to the working directory; empty
    /// keeps everything in memory only.
    pub data_dir: std::path::PathBuf,
    /// Disk bytes the posted scenes kept under `data_dir/scenes` may take
    /// together; a POST beyond gets 507 naming this key.
    pub posted_scene_bytes: u64,
}

/// Per-request limits that keep one request from monopolising the service.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Largest request body in bytes (413 beyond).
    pub max_body_bytes: usize,
    /// Largest scene upload with its assets (`multipart/form-data` or an
    /// archive on `POST /v1/scenes`), bytes as sent (413 beyond).
    pub max_upload_bytes: u64,
    /// Most assets (archive entries) in one scene upload (422 naming the
    /// first one over).
    pub max_assets: usize,
    /// Largest asset of an upload once unpacked, bytes (422 naming it).
    pub max_asset_bytes: u64,
    /// Largest sum of an archive's unpacked entries, bytes, skipped ones
    /// included (of a tar, its headers too; 422 naming the entry that
    /// passes it).
    pub max_unpacked_bytes: u64,
    /// Most unpacked bytes per packed byte of a zip's entry, or of a gzipped
    /// tar as a whole, past the first MiB (422 naming the entry: a bomb).
    pub max_compression_ratio: u64,
    /// Uploads and records imports read at once (each up to
    /// `max_upload_bytes` in memory, an import until its records are
    /// checked and added); more get 503 with `Retry-After`.
    pub max_concurrent_uploads: usize,
    /// Most points in one point query.
    pub max_points: usize,
    /// Most hemisphere samples per estimate.
    pub max_samples: usize,
    /// Largest tile area in pixels.
    pub max_tile_area: usize,
    /// CPU jobs queued or running at once (503 beyond).
    pub max_queued_jobs: usize,
    /// Longest expected wait in the CPU queue, in seconds, at which a job is
    /// still admitted (503 beyond).
    pub max_queue_wait_secs: f64,
    /// Wall-clock deadline of a request in seconds (504 beyond).
    pub request_deadline_secs: u64,
    /// Most paths one request may trace, as estimated before it starts
    /// (422 naming `estimated_paths` beyond).
    pub max_paths_per_request: u64,
}

/// Where scenes come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenesConfig {
    /// Directory of scene documents, relative to the working directory.
    pub dir: PathBuf,
    /// Most scenes loaded at once (startup and posted together).
    pub max_scenes: usize,
    /// Most triangles over all loaded scenes together.
    pub max_triangles: usize,
    /// Most bytes held by all loaded scenes together (geometry, acceleration
    /// structures and environment maps, as `Scene::heap_bytes` counts them).
    pub max_scene_bytes: u64,
    /// Mitsuba XML files of the directory: approximate what the scene model
    /// cannot represent (each scene's summary says what) instead of skipping
    /// the scene.
    pub lenient: bool,
}

impl Config {
    /// Merges the layers described in the module docs and validates the result.
    ///
    /// `env` is passed in (rather than read here) so tests control it; the binary
    /// passes `std::env::vars()`.
    pub fn load(
        file: Option<&Path>,
        env: impl IntoIterator<Item = (String, String)>,
        bind: Option<SocketAddr>,
    ) -> Result<Config, ConfigError> {
        let mut table: Table = DEFAULT_TOML
            .parse()
            .expect("the embedded config/default.toml is valid TOML (checked by a unit test)");
        if let Some(path) = file {
            let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
                path: path.to_owned(),
                source,
            })?;
            let overlay: Table = text.parse().map_err(|source| ConfigError::Parse {
                path: path.to_owned(),
                source,
            })?;
            merge_file(&mut table, overlay, &path.display().to_string())?;
        }
        for (name, value) in env {
            apply_env(&mut table, &name, &value)?;
        }
        let mut config: Config = Value::Table(table).try_into()?;
        if let Some(bind) = bind {
            config.server.bind = bind;
        }
        config.validate()?;
        Ok(config)
    }

    /// The defaults alone (what `serve` runs with when nothing overrides them).
    pub fn default_config() -> Config {
        Config::load(None, std::iter::empty(), None)
            .expect("the embedded config/default.toml is valid (checked by a unit test)")
    }

    /// Rejects values that cannot work: zero limits or budgets, an empty scenes path.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("limits.max_body_bytes", self.limits.max_body_bytes as u64),
            ("limits.max_upload_bytes", self.limits.max_upload_bytes),
            ("limits.max_assets", self.limits.max_assets as u64),
            ("limits.max_asset_bytes", self.limits.max_asset_bytes),
            ("limits.max_unpacked_bytes", self.limits.max_unpacked_bytes),
            (
                "limits.max_compression_ratio",
                self.limits.max_compression_ratio,
            ),
            ("limits.max_points", self.limits.max_points as u64),
            ("limits.max_samples", self.limits.max_samples as u64),
            ("limits.max_tile_area", self.limits.max_tile_area as u64),
            ("limits.max_queued_jobs", self.limits.max_queued_jobs as u64),
            (
                "limits.max_concurrent_uploads",
                self.limits.max_concurrent_uploads as u64,
            ),
            ("cache.posted_scene_bytes", self.cache.posted_scene_bytes),
            (
                "limits.request_deadline_secs",
                self.limits.request_deadline_secs,
            ),
            (
                "limits.max_paths_per_request",
                self.limits.max_paths_per_request,
            ),
            (
                "server.header_read_timeout_secs",
                self.server.header_read_timeout_secs,
            ),
            ("server.max_connections", self.server.max_connections as u64),
            ("cache.factorisation_bytes", self.cache.factorisation_bytes),
            ("cache.irradiance_bytes", self.cache.irradiance_bytes),
            ("cache.tile_bytes", self.cache.tile_bytes),
            ("cluster.shared_parts", self.cluster.shared_parts),
        ];
        for (field, value) in positive {
            if value == 0 {
                return Err(ConfigError::Invalid {
                    field,
                    reason: "must be greater than zero".into(),
                });
            }
        }
        if self.limits.max_queue_wait_secs.is_nan() || self.limits.max_queue_wait_secs <= 0.0 {
            return Err(ConfigError::Invalid {
                field: "limits.max_queue_wait_secs",
                reason: "must be greater than zero".into(),
            });
        }
        if !self.cluster.redis_url.is_empty()
            && let Err(err) = redis::Client::open(self.cluster.redis_url.as_str())
        {
            return Err(ConfigError::Invalid {
                field: "cluster.redis_url",
                reason: format!("is not a Redis URL: {err}"),
            });
        }
        if self.cluster.redis_prefix.is_empty() || self.cluster.redis_prefix.contains(' ') {
            return Err(ConfigError::Invalid {
                field: "cluster.redis_prefix",
                reason: "must be non-empty and without spaces".into(),
            });
        }
        if let Some(bad) = self
            .server
            .allowed_origins()
            .find(|origin| !is_origin(origin))
        {
            return Err(ConfigError::Invalid {
                field: "server.allowed_origins",
                reason: format!(
                    "lists {bad:?}, which is not an origin of the form scheme://host[:port]"
                ),
            });
        }
        if self.scenes.dir.as_os_str().is_empty() {
            return Err(ConfigError::Invalid {
                field: "scenes.dir",
                reason: "must not be empty".into(),
            });
        }
        let scene_budgets = [
            ("scenes.max_scenes", self.scenes.max_scenes as u64),
            ("scenes.max_triangles", self.scenes.max_triangles as u64),
            ("scenes.max_scene_bytes", self.scenes.max_scene_bytes),
        ];
        for (field, value) in scene_budgets {
            if value == 0 {
                return Err(ConfigError::Invalid {
                    field,
                    reason: "must be greater than zero".into(),
                });
            }
        }
        Ok(())
    }
}

impl ServerConfig {
    /// The origins of `allowed_origins`, trimmed, without a trailing `/`.
    pub fn allowed_origins(&self) -> impl Iterator<Item = &str> {
        self.allowed_origins
            .split(',')
            .map(|o| o.trim().trim_end_matches('/'))
            .filter(|o| !o.is_empty())
    }

    /// Runtime threads with 0 resolved to the number of cores.
    pub fn runtime_threads(&self) -> usize {
        resolve_threads(self.runtime_threads)
    }

    /// CPU pool threads with 0 resolved to the number of cores.
    pub fn worker_threads(&self) -> usize {
        resolve_threads(self.worker_threads)
    }
}

/// Whether `origin` is `scheme://host[:port]`, as browsers send it in `Origin`.
fn is_origin(origin: &str) -> bool {
    url::Url::parse(origin).is_ok_and(|u| {
        u.has_host()
            && u.path() == "/"
            && u.query().is_none()
            && u.username().is_empty()
            && !origin.ends_with('/')
    })
}

impl Limits {
    /// The request deadline as a duration.
    pub fn request_deadline(&self) -> Duration {
        Duration::from_secs(self.request_deadline_secs)
    }

    /// `max_samples` as the per-point sample cap a point query's error
    /// target takes when it names none.
    pub fn target_max_samples(&self) -> u32 {
        u32::try_from(self.max_samples).unwrap_or(u32::MAX)
    }

    /// Refuses a request whose estimated paths exceed `max_paths_per_request`
    /// (422 `limit_exceeded` naming `estimated_paths`). Each per-request
    /// limit alone is modest, but they multiply: a one-pixel tile with 4096
    /// record directions × 65,536 paths each cost 16 CPU-minutes.
    pub fn check_work(&self, estimated_paths: u64) -> Result<(), super::error::ApiError> {
        super::error::ApiError::check_limit(
            "estimated_paths",
            estimated_paths,
            self.max_paths_per_request,
        )
    }

    /// Refuses irradiance-cache records of more than 1/[`RECORD_SHARE`] of
    /// the work budget each (422 naming `estimated_paths_per_record`): a
    /// record is the unit at which cancelled work stops, so it must be short.
    pub fn check_record_work(&self, paths_per_record: u64) -> Result<(), super::error::ApiError> {
        super::error::ApiError::check_limit(
            "estimated_paths_per_record",
            paths_per_record,
            self.max_paths_per_request / RECORD_SHARE,
        )
    }
}

fn resolve_threads(configured: usize) -> usize {
    if configured > 0 {
        configured
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// Copies every key of `overlay` onto `base`, refusing sections and keys `base` lacks.
fn merge_file(base: &mut Table, overlay: Table, origin: &str) -> Result<(), ConfigError> {
    for (section, value) in overlay {
        let Some(Value::Table(target)) = base.get_mut(&section) else {
            return Err(ConfigError::UnknownKey {
                origin: origin.into(),
                key: section,
            });
        };
        let Value::Table(entries) = value else {
            return Err(ConfigError::BadValue {
                origin: origin.into(),
                key: section,
                expected: "a table",
                value: value.to_string(),
            });
        };
        for (key, value) in entries {
            if !target.contains_key(&key) {
                return Err(ConfigError::UnknownKey {
                    origin: origin.into(),
                    key: format!("{section}.{key}"),
                });
            }
            target.insert(key, value);
        }
    }
    Ok(())
}

/// Applies one `BMC_<SECTION>__<KEY>` variable; other variables are ignored.
fn apply_env(base: &mut Table, name: &str, raw: &str) -> Result<(), ConfigError> {
    let Some((section, key)) = name
        .get(..ENV_PREFIX.len())
        .filter(|prefix| prefix.eq_ignore_ascii_case(ENV_PREFIX))
        .and_then(|_| name[ENV_PREFIX.len()..].split_once("__"))
    else {
        return Ok(());
    };
    let (section, key) = (section.to_ascii_lowercase(), key.to_ascii_lowercase());
    let unknown = || ConfigError::UnknownKey {
        origin: format!("environment variable {name}"),
        key: format!("{section}.{key}"),
    };
    let slot = base
        .get_mut(&section)
        .and_then(Value::as_table_mut)
        .and_then(|table| table.get_mut(&key))
        .ok_or_else(unknown)?;
    let bad = |expected| ConfigError::BadValue {
        origin: format!("environment variable {name}"),
        key: format!("{section}.{key}"),
        expected,
        value: raw.into(),
    };
    *slot = match slot {
        Value::Integer(_) => Value::Integer(raw.trim().parse().map_err(|_| bad("an integer"))?),
        Value::Boolean(_) => Value::Boolean(raw.trim().parse().map_err(|_| bad("true or false"))?),
        Value::Float(_) => Value::Float(raw.trim().parse().map_err(|_| bad("a number"))?),
        _ => Value::String(raw.into()),
    };
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn defaults_parse_and_validate() {
        let config = Config::default_config();
        assert_eq!(config.server.bind, "127.0.0.1:8080".parse().unwrap());
        assert_eq!(config.scenes.dir, PathBuf::from("scenes"));
        assert!(config.server.worker_threads() >= 1);
    }

    #[test]
    fn file_overrides_some_keys_and_keeps_the_rest() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, "[limits]\nmax_points = 7\n").unwrap();
        let config = Config::load(Some(&path), env(&[]), None).unwrap();
        assert_eq!(config.limits.max_points, 7);
        assert_eq!(
            config.limits.max_samples,
            Config::default_config().limits.max_samples
        );
    }

    #[test]
    fn unknown_key_in_file_is_rejected_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, "[limits]\nmax_pionts = 7\n").unwrap();
        let err = Config::load(Some(&path), env(&[]), None).unwrap_err();
        assert!(err.to_string().contains("limits.max_pionts"), "{err}");
    }

    #[test]
    fn environment_overrides_file_and_bind_flag_overrides_all() {
        let config = Config::load(
            None,
            env(&[
                ("BMC_LIMITS__MAX_POINTS", "12"),
                ("bmc_server__bind", "127.0.0.1:9999"),
                ("BMC_SCENES__DIR", "/tmp/s"),
                ("BMC_UNRELATED", "x"),
                ("PATH", "/bin"),
            ]),
            Some("127.0.0.1:0".parse().unwrap()),
        )
        .unwrap();
        assert_eq!(config.limits.max_points, 12);
        assert_eq!(config.scenes.dir, PathBuf::from("/tmp/s"));
        assert_eq!(config.server.bind.port(), 0);
    }

    #[test]
    fn bad_environment_values_name_the_variable() {
        let err = Config::load(None, env(&[("BMC_LIMITS__MAX_POINTS", "many")]), None).unwrap_err();
        assert!(err.to_string().contains("BMC_LIMITS__MAX_POINTS"), "{err}");
        let err = Config::load(None, env(&[("BMC_LIMITS__NOPE", "1")]), None).unwrap_err();
        assert!(err.to_string().contains("limits.nope"), "{err}");
    }

    #[test]
    fn zero_limits_are_rejected_with_the_field() {
        let err =
            Config::load(None, env(&[("BMC_LIMITS__MAX_QUEUED_JOBS", "0")]), None).unwrap_err();
        assert!(
            matches!(
                err,
                ConfigError::Invalid {
                    field: "limits.max_queued_jobs",
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn scene_budgets_are_set_by_environment_and_must_be_positive() {
        let config =
            Config::load(None, env(&[("BMC_SCENES__MAX_TRIANGLES", "1234")]), None).unwrap();
        assert_eq!(config.scenes.max_triangles, 1234);
        for key in ["MAX_SCENES", "MAX_TRIANGLES", "MAX_SCENE_BYTES"] {
            let name = format!("BMC_SCENES__{key}");
            let err = Config::load(None, env(&[(&name, "0")]), None).unwrap_err();
            let expected = format!("scenes.{}", key.to_lowercase());
            assert!(
                matches!(&err, ConfigError::Invalid { field, .. } if *field == expected),
                "{err}"
            );
        }
    }

    #[test]
    fn wrong_type_in_file_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, "[server]\nbind = 5\n").unwrap();
        let err = Config::load(Some(&path), env(&[]), None).unwrap_err();
        assert!(err.to_string().contains("bind"), "{err}");
    }
}
