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

use crate::image::{ImageEncoding, ToneMap};
use crate::integrator::Integrator;
use crate::integrator::cached::{CachedIntegrator, CachedTileReport};
use crate::render::{Cancel, RenderedTile, TileRequest, Transport};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::integrator_doc::{CachedSetup, IntegratorDoc, cached_setup};
use crate::service::metrics::RAYS_TRACED;
use crate::service::state::AppState;

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
    pub estimator: IntegratorDoc,
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
    crate::render::path::DEFAULT_MAX_DEPTH
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
    let scene = state.scenes.get_or_404(&id)?;
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
        Integrator::Cache => Some(doc.estimator.resolve(limits)?),
        Integrator::Path => None,
    };
    let camera_paths = area * u64::from(doc.samples_per_pixel);
    let record_paths = cached
        .as_ref()
        .map_or(0, |c| area.saturating_mul(c.config.paths_per_record()));
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
