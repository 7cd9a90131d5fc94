//! `POST /v1/scenes/{id}/tiles`: a rectangle of the scene camera's image as
//! EXR (R, G, B and a per-pixel `variance` channel), tone-mapped sRGB PNG, or
//! JSON floats.
//!
//! The body of a JSON tile is the serde form of [`crate::image::Image`]
//! (`width`, `height`, `rgb`, `variance`); the tile's position and the rays it
//! took travel in headers for every format, so binary tiles carry them too:
//! `x-tile-x`, `x-tile-y`, `x-rays`.

use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{HeaderName, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use utoipa::ToSchema;

use crate::image::{ImageEncoding, ToneMap};
use crate::render::{RenderError, ShadingMethod, TileRequest};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::ApiJson;
use crate::service::metrics::RAYS_TRACED;
use crate::service::routes::scenes::scene_or_404;
use crate::service::state::AppState;

/// How each camera ray is shaded.
#[derive(Debug, Clone, Copy, Default, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TileMethod {
    /// Unidirectional path tracing with next-event estimation and MIS.
    #[default]
    Path,
}

#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TileEstimatorDoc {
    #[serde(default)]
    pub method: TileMethod,
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
    /// Seed of every random stream; pixel values depend only on it and the
    /// pixel position, not on the tiling. Default 1.
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
    Path(id): Path<String>,
    ApiJson(doc): ApiJson<TileRequestDoc>,
) -> Result<Response, ApiError> {
    let scene = scene_or_404(&state, &id)?;
    let limits = &state.config.limits;
    let area = u64::from(doc.width) * u64::from(doc.height);
    ApiError::check_limit(
        "width",
        usize::try_from(area).unwrap_or(usize::MAX),
        limits.max_tile_area,
    )?;
    ApiError::check_limit(
        "samples_per_pixel",
        doc.samples_per_pixel as usize,
        limits.max_samples,
    )?;
    let tone_map = ToneMap {
        exposure: doc.exposure,
    };
    if !doc.exposure.is_finite() {
        return Err(ApiError::invalid("exposure", "must be a finite number"));
    }
    let TileMethod::Path = doc.estimator.method;
    let request = TileRequest {
        x: doc.x,
        y: doc.y,
        width: doc.width,
        height: doc.height,
        samples_per_pixel: doc.samples_per_pixel,
        max_depth: doc.max_depth,
        seed: doc.seed,
        method: ShadingMethod::PathTracing,
    };
    // Checked here too, so a bad rectangle never takes a CPU slot.
    request
        .validate(scene.transport.scene().camera.resolution())
        .map_err(render_error)?;
    let format = doc.format;
    let (tile, body) = state
        .pool
        .run(move || {
            let tile = scene
                .transport
                .render_tile(&request)
                .map_err(render_error)?;
            let body = tile
                .image
                .encode(format, tone_map)
                .map_err(|e| ApiError::Internal {
                    message: format!("cannot encode the tile: {e}"),
                })?;
            Ok::<_, ApiError>((tile, body))
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
        ],
        body,
    )
        .into_response())
}

/// A tile validation error as a 422 naming the request field.
fn render_error(err: RenderError) -> ApiError {
    match &err {
        RenderError::InvalidOption { field, .. } => ApiError::invalid(*field, err.to_string()),
        RenderError::InvalidPoint { field, .. } => ApiError::invalid(*field, err.to_string()),
        RenderError::PointsRow { .. } => ApiError::Internal {
            message: err.to_string(),
        },
    }
}
