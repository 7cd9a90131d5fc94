//! `POST /v1/scenes/{id}/tiles`: a rectangle of the scene camera's image as
//! EXR (R, G, B and a per-pixel `variance` channel), tone-mapped sRGB PNG, or
//! JSON floats.
//!
//! The body of a JSON tile is the serde form of [`crate::image::Image`]
//! (`width`, `height`, `rgb`, `variance`); the tile's position and the rays it
//! took travel in headers for every format, so binary tiles carry them too:
//! `x-tile-x`, `x-tile-y`, `x-rays`.

use std::sync::Arc;

use axum::extract::State;
use axum::http::{HeaderName, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use utoipa::ToSchema;

use crate::cache::{CacheConfig, CacheError, IrradianceCache, RecordRuleSpec};
use crate::image::{ImageEncoding, ToneMap};
use crate::integrator::Integrator;
use crate::integrator::cached::{
    CacheShadingOptions, CachedIntegrator, CachedShading, CachedTileReport, default_rule_spec,
};
use crate::render::{Cancel, RenderedTile, TileRequest, Transport};
use crate::service::config::Limits;
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::irradiance_caches::SceneCache;
use crate::service::metrics::RAYS_TRACED;
use crate::service::routes::scenes::scene_or_404;
use crate::service::scenes::LoadedScene;
use crate::service::state::AppState;

/// Number of θ_r nodes of the glossy BMC rule (`integrator::cached::GlossyRule`).
const GLOSSY_BINS: usize = 16;

/// The tile estimator; every field but `method` applies to `cache` only, and
/// every one is optional.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TileEstimatorDoc {
    /// `cache` (default; `bmc` is an alias): the Bayesian irradiance cache —
    /// light sampling for direct light, `(k_d/π)·E` interpolated from BMC
    /// records for diffuse indirect light, BMC with the Phong density for
    /// glossy reflection. `path`: path tracing with NEE and MIS, the
    /// unbiased reference.
    #[serde(default)]
    #[schema(value_type = String, example = "cache")]
    pub method: Integrator,
    /// Directions per record (spherical Fibonacci), 1..=`limits.max_samples`; default 64.
    pub samples: Option<u32>,
    /// SE kernel lengthscale of the records' GP prior (chordal units); default 0.5.
    pub lengthscale: Option<f64>,
    /// Noise variance σ_n² relative to σ² = 1; default 1e-8.
    pub noise: Option<f64>,
    /// Paths traced per record direction and averaged; default 1.
    pub paths_per_direction: Option<u32>,
    /// Levels of records whose rays gather through the cache (Radiance-style
    /// ambient bounces: direct light plus cached indirect irradiance at each
    /// ray's hit), 0..=8; 0 = records trace full paths. Default 0.
    pub ambient_bounces: Option<u32>,
    /// Ward's accuracy a ∈ (0, 1]; smaller places more records. Default 0.5.
    pub accuracy: Option<f64>,
    /// Also place a record where the interpolated relative standard error
    /// exceeds this (variance-driven placement); default off.
    pub relative_error_target: Option<f64>,
    /// Shadow ray between a point and each record it uses (no light leaks
    /// through thin walls); default false.
    pub occlusion_check: Option<bool>,
    /// Light samples per shading point for direct light; default 16.
    pub light_samples: Option<u32>,
    /// Bit-identical output whatever the thread count and whatever ran
    /// before: records are placed in a private cache for this tile, then
    /// published to the shared one. Default false.
    pub reproducible: Option<bool>,
    /// Use the scene's shared cache (default true); `false` computes every
    /// record for this request alone and keeps none.
    pub cache: Option<bool>,
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TileRequestDoc {
    /// Column of the tile's left edge (pixels from the image's left).
    pub x: u32,
    /// Row of the tile's top edge (pixels from the image's top).
    pub y: u32,
    /// Width · height at most `limits.max_tile_area`.
    pub width: u32,
    pub height: u32,
    /// Encoding of the response body: `exr` (default), `png` or `json`.
    #[serde(default = "default_format")]
    #[schema(value_type = String)]
    pub format: ImageEncoding,
    #[serde(default)]
    pub estimator: TileEstimatorDoc,
    /// Camera rays per pixel, 1..=`limits.max_samples`; default 1.
    #[serde(default = "default_spp")]
    pub samples_per_pixel: u32,
    /// Longest path in segments; default 16.
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    /// Seed of every random stream; default 1. With `path`, a pixel's value
    /// depends only on the seed and its position (not on the tiling); with
    /// `bmc` and `reproducible`, the same request gives the same bytes.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// PNG only: exposure in stops (values scaled by 2^exposure); default 0.
    #[serde(default)]
    pub exposure: f32,
}

fn default_format() -> ImageEncoding {
    ImageEncoding::Exr
}

fn default_spp() -> u32 {
    1
}

fn default_max_depth() -> u32 {
    16
}

fn default_seed() -> u64 {
    1
}

/// One tile of the scene camera's image.
#[utoipa::path(post, path = "/v1/scenes/{id}/tiles", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body = TileRequestDoc,
    responses((status = 200, description = "The tile: EXR, PNG or JSON (`{width, height, rgb, variance}`); \
                headers x-tile-x, x-tile-y, x-rays",
               content((Vec<u8> = "image/x-exr"), (Vec<u8> = "image/png"), (Object = "application/json"))),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn tile(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    ApiJson(doc): ApiJson<TileRequestDoc>,
) -> Result<Response, ApiError> {
    let scene = scene_or_404(&state, &id)?;
    let limits = &state.config.limits;
    let area = u64::from(doc.width) * u64::from(doc.height);
    ApiError::check_limit("width*height", area, limits.max_tile_area as u64)?;
    ApiError::check_limit(
        "samples_per_pixel",
        u64::from(doc.samples_per_pixel),
        limits.max_samples as u64,
    )?;
    let tone_map = ToneMap {
        exposure: doc.exposure,
    };
    if !doc.exposure.is_finite() {
        return Err(ApiError::invalid("exposure", "must be a finite number"));
    }
    let request = TileRequest {
        x: doc.x,
        y: doc.y,
        width: doc.width,
        height: doc.height,
        samples_per_pixel: doc.samples_per_pixel,
        max_depth: doc.max_depth,
        seed: doc.seed,
    };
    // Checked here too, so a bad rectangle never takes a CPU slot.
    request.validate(scene.transport.scene().camera.resolution())?;
    // The work, bounded before it starts: camera paths, plus at most one
    // record per pixel (placement points are pixel centres) for `bmc`.
    let cached = match doc.estimator.method {
        Integrator::Cache => Some(CachedSpec::resolve(&doc.estimator, limits)?),
        Integrator::Path => None,
    };
    let camera_paths = area * u64::from(doc.samples_per_pixel);
    let record_paths = cached
        .as_ref()
        .map_or(0, |c| area.saturating_mul(c.paths_per_record()));
    limits.check_work(camera_paths.saturating_add(record_paths))?;
    let format = doc.format;
    let shared = state.clone();
    let (tile, report, body) = state
        .pool
        .run(move |cancel| {
            // On the pool: a new configuration factorises its record rule.
            let cached = cached
                .map(|spec| cached_setup(&shared, &scene, spec, doc.max_depth))
                .transpose()?;
            let (tile, report) = render(&scene.transport, &request, cached, cancel)?;
            let body = tile
                .image
                .encode(format, tone_map)
                .map_err(|e| ApiError::Internal {
                    message: format!("cannot encode the tile: {e}"),
                })?;
            Ok::<_, ApiError>((tile, report, body))
        })
        .await??;
    ::metrics::counter!(RAYS_TRACED).increment(tile.rays);
    let number = |n: u64| HeaderValue::from(n);
    Ok((
        [
            (
                header::CONTENT_TYPE,
                HeaderValue::from_static(format.content_type()),
            ),
            (
                HeaderName::from_static("x-tile-x"),
                number(u64::from(tile.x)),
            ),
            (
                HeaderName::from_static("x-tile-y"),
                number(u64::from(tile.y)),
            ),
            (HeaderName::from_static("x-rays"), number(tile.rays)),
            (
                HeaderName::from_static("x-records-created"),
                number(report.map_or(0, |r| r.placement.records_created)),
            ),
            (
                HeaderName::from_static("x-cache-hits"),
                number(report.map_or(0, |r| r.shading.cache_hits)),
            ),
        ],
        body,
    )
        .into_response())
}

/// The shared cache and per-request options of a `bmc` tile, or the
/// estimator field at fault.
pub(crate) struct CachedSetup {
    entry: Arc<SceneCache>,
    pub shading: CachedShading,
    /// `Some` when the request disabled the shared cache: its private cache.
    private: Option<IrradianceCache>,
}

impl CachedSetup {
    /// The cache the request reads and extends.
    pub fn cache(&self) -> &IrradianceCache {
        self.private.as_ref().unwrap_or(&self.entry.cache)
    }
}

/// A `bmc` estimator document with its defaults filled in and its sample
/// count checked: cheap, so it runs before the request takes a CPU slot.
pub(crate) struct CachedSpec {
    spec: RecordRuleSpec,
    options: CacheShadingOptions,
    /// Whether the request reads and extends the scene's shared cache.
    shared: bool,
}

impl CachedSpec {
    /// Fills in the defaults and checks the sample count and each record's
    /// paths against the limits.
    pub(crate) fn resolve(e: &TileEstimatorDoc, limits: &Limits) -> Result<CachedSpec, ApiError> {
        let samples = e.samples.unwrap_or(64);
        ApiError::check_limit(
            "estimator.samples",
            u64::from(samples),
            limits.max_samples as u64,
        )?;
        let mut spec: RecordRuleSpec = default_rule_spec();
        spec.samples.count = samples as usize;
        if let Some(lengthscale) = e.lengthscale {
            spec.kernel.lengthscale = lengthscale;
        }
        if let Some(noise) = e.noise {
            spec.kernel.noise = noise;
        }
        let defaults = CacheShadingOptions::default();
        let options = CacheShadingOptions {
            accuracy: e.accuracy.unwrap_or(defaults.accuracy),
            relative_error_target: e.relative_error_target,
            occlusion_check: e.occlusion_check.unwrap_or(defaults.occlusion_check),
            reproducible: e.reproducible.unwrap_or(defaults.reproducible),
            light_samples: e.light_samples.unwrap_or(defaults.light_samples),
            paths_per_direction: e
                .paths_per_direction
                .unwrap_or(defaults.paths_per_direction),
            ambient_bounces: e.ambient_bounces.unwrap_or(defaults.ambient_bounces),
            ..defaults
        };
        // Validated before the budget, so an out-of-range knob is named as such.
        options.validate().map_err(estimator_error)?;
        let resolved = CachedSpec {
            spec,
            options,
            shared: e.cache.unwrap_or(true),
        };
        limits.check_record_work(resolved.paths_per_record())?;
        Ok(resolved)
    }

    /// Paths one record may trace: its directions times the paths per
    /// direction, once more per ambient level that re-gathers them. Records
    /// that ambient levels place at secondary hits are not counted: how many
    /// there are depends on what the cache already holds.
    pub(crate) fn paths_per_record(&self) -> u64 {
        self.spec.samples.count as u64
            * u64::from(self.options.paths_per_direction)
            * (1 + u64::from(self.options.ambient_bounces))
    }
}

/// The cache and rules for estimator `e` on `scene` with paths of up to
/// `max_depth` segments counted from the camera (tiles) or viewer (radiance
/// queries), so both share records.
pub(crate) fn cached_setup(
    state: &AppState,
    scene: &LoadedScene,
    resolved: CachedSpec,
    max_depth: u32,
) -> Result<CachedSetup, ApiError> {
    let CachedSpec {
        spec,
        options,
        shared,
    } = resolved;
    // What the records' values depend on: their rule and the path depth.
    let configuration = serde_json::json!({
        "rule": spec,
        "paths_per_direction": options.paths_per_direction,
        "ambient_bounces": options.ambient_bounces,
        "max_depth": max_depth,
        "glossy_bins": GLOSSY_BINS,
    });
    let quadratures = state.quadratures.clone();
    let entry = state
        .irradiance_caches
        .get_or_create(scene, &configuration, CacheConfig::default(), || {
            CachedShading::new(spec, GLOSSY_BINS, quadratures, options)
        })
        .map_err(estimator_error)?;
    let shading = entry
        .shading
        .with_options(options)
        .map_err(estimator_error)?;
    let private = if shared {
        None
    } else {
        Some(IrradianceCache::new(*entry.cache.config()).map_err(estimator_error)?)
    };
    Ok(CachedSetup {
        entry,
        shading,
        private,
    })
}

/// Renders on the CPU pool: path tracing, or through the irradiance cache.
fn render(
    transport: &Transport,
    request: &TileRequest,
    cached: Option<CachedSetup>,
    cancel: &Cancel,
) -> Result<(RenderedTile, Option<CachedTileReport>), ApiError> {
    match cached {
        None => Ok((transport.render_tile(request, cancel)?, None)),
        Some(setup) => {
            let integrator = CachedIntegrator {
                transport,
                cache: setup.cache(),
                shading: &setup.shading,
            };
            let (tile, report) = integrator.render_tile(request, cancel)?;
            Ok((tile, Some(report)))
        }
    }
}

/// A cache or rule error as a 422 naming the estimator field.
pub(crate) fn estimator_error(err: CacheError) -> ApiError {
    let field = match err.field() {
        Some("kernel.lengthscale" | "lengthscale") => "estimator.lengthscale".to_owned(),
        Some(field) => format!("estimator.{field}"),
        None => "estimator".to_owned(),
    };
    ApiError::invalid(field, err.to_string())
}
