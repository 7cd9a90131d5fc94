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
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use utoipa::ToSchema;

use crate::image::{ImageEncoding, ToneMap};
use crate::integrator::progressive::TileParams;
use crate::integrator::{IntegratorSpec, Preset};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::metrics::RAYS_TRACED;
use crate::service::state::AppState;
use crate::service::tile_render::{check_work, render_progressive, tile_job};
use crate::service::tile_response::tile_headers;

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
    /// Quality preset whose knobs the fields below override: `draft`,
    /// `preview` (default), `interactive`, `standard` or `final` (see
    /// `integrator::preset`).
    #[schema(value_type = Option<String>)]
    pub preset: Option<Preset>,
    /// Pass to return, 0-based: the mean of passes `0..=pass`; default the
    /// preset's last (its final image). With an explicit `samples_per_pixel`
    /// the tile is one pass of that many rays (so `pass` may only be 0).
    pub pass: Option<u32>,
    /// The integrator and its knobs, over the preset's (`method` `cache`,
    /// the default, or `path`).
    #[serde(default)]
    pub estimator: IntegratorSpec,
    /// Camera rays per pixel in each pass, 1..=`limits.max_samples`;
    /// default the preset's.
    pub samples_per_pixel: Option<u32>,
    /// Longest path in segments from the camera; default the scene's (its
    /// Mitsuba integrator's `max_depth`), else the preset's.
    pub max_depth: Option<u32>,
    /// Seed of every random stream; default 1. With `path`, a pixel's value
    /// depends only on the seed and its position (not on the tiling); with
    /// `cache` and `reproducible` (the presets' default), the same request
    /// gives the same bytes.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// PNG only: exposure in stops (values scaled by 2^exposure); default 0.
    #[serde(default)]
    pub exposure: f32,
    /// Denoise the tile with the camera's first-hit guides, each pixel
    /// with a calibrated standard error (docs/math.md §16.6, §16.7);
    /// default: as the preset does on the scene (path traced scenes
    /// denoised, cached ones not; `GET /v1/presets`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoise: Option<bool>,
}

fn default_format() -> ImageEncoding {
    ImageEncoding::Exr
}

fn default_seed() -> u64 {
    1
}

/// One tile of the scene camera's image.
#[utoipa::path(post, path = "/v1/scenes/{id}/tiles", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body = TileRequestDoc,
    responses((status = 200, description = "The tile: EXR, PNG or JSON (`{width, height, rgb, variance}`); \
                headers x-tile-x, x-tile-y, x-rays, x-records-created, x-cache-hits, x-passes, \
                x-passes-rendered",
               content((Vec<u8> = "image/x-exr"), (Vec<u8> = "image/png"), (Object = "application/json"))),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn tile(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    ApiJson(doc): ApiJson<TileRequestDoc>,
) -> Result<Response, ApiError> {
    let scene = state.scene(&id).await?;
    let limits = &state.config.limits;
    if !doc.exposure.is_finite() {
        return Err(ApiError::invalid("exposure", "must be a finite number"));
    }
    let tone_map = ToneMap {
        exposure: doc.exposure,
    };
    let params = TileParams {
        x: doc.x,
        y: doc.y,
        width: doc.width,
        height: doc.height,
        preset: doc.preset.unwrap_or_default(),
        samples_per_pixel: doc.samples_per_pixel,
        pass: doc.pass,
        max_depth: doc.max_depth,
        seed: doc.seed,
        estimator: doc.estimator,
        denoise: doc.denoise,
    };
    let job = tile_job(&params, scene.transport.scene(), limits)?;
    check_work(&job, scene.transport.scene(), limits)?;
    let format = doc.format;
    let shared = state.clone();
    let (tile, body) = state
        .pool
        .run(move |cancel| {
            let tile = render_progressive(&shared, &scene, &job, cancel)?;
            let body = tile.image.encode(format, tone_map)?;
            Ok::<_, ApiError>((tile, body))
        })
        .await??;
    ::metrics::counter!(RAYS_TRACED).increment(tile.rays);
    let mut response = body.into_response();
    tile_headers(response.headers_mut(), format, &job, &tile);
    Ok(response)
}
