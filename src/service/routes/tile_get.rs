//! `GET /v1/scenes/{id}/tiles/{tx}/{ty}.{png|exr|json}`: tiles of the scene
//! camera's image on a grid of `size`-pixel squares, as browsers, HTTP
//! caches and tile viewers fetch them.
//!
//! Every tile is reproducible (the cache integrator's `reproducible` mode
//! with the preset's knobs): the same URL gives the same bytes whatever ran
//! before, on any replica and after a restart, so the response carries a
//! strong `ETag` — a hash of the service version, the scene's content
//! digest and the normalised parameters — and `Cache-Control`; a request
//! whose `If-None-Match` names it gets 304 without any rendering.
//!
//! Query parameters (all optional): `size` (tile side, default
//! [`DEFAULT_TILE_SIZE`]), `preset` (`draft`, `preview` default, `interactive`, `standard`, `final`),
//! `pass` (0-based; default the preset's last: the final image; pass `k`
//! is the mean of passes `0..=k`), `seed` (default 1), `exposure` (stops,
//! PNG radiance only), `aov` (`radiance` default, `std_dev`, `records`) and
//! `scale` (`std_dev` PNG only: the relative standard error at the top of
//! the colour map, default [`DEFAULT_STD_DEV_SCALE`]) and `denoise`
//! (`true` filters the tile with its own guides and error bars,
//! docs/math.md §16.6; default `false`).
//!
//! AOVs: `std_dev` is the per-pixel standard error — as a PNG, the
//! relative standard error through a false-colour map (its scale in the
//! `x-std-dev-scale` header); as EXR or JSON, the absolute standard error
//! in every channel. `records` shows the tile's irradiance-cache records:
//! a transparent PNG overlay (centres and validity circles) or JSON
//! (positions, radii, irradiance, pixel positions).

use std::sync::Arc;
use std::time::Instant;

use axum::extract::{FromRequestParts, Path, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::image::{ImageEncoding, ToneMap, png_io};
use crate::integrator::cached::{RecordView, record_overlay, record_views};
use crate::integrator::progressive::TileParams;
use crate::integrator::{IntegratorSpec, Preset};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::ApiQuery;
use crate::service::metrics::RAYS_TRACED;
use crate::service::state::AppState;
use crate::service::tile_render::{check_work, render_progressive, tile_job};
use crate::service::tile_response::{SERVER_TIMING, X_RECORDS, X_STD_DEV_SCALE, tile_headers};

/// Tile side when `size` is not given, pixels.
pub const DEFAULT_TILE_SIZE: u32 = 64;
/// Relative standard error at the top of the `std_dev` PNG's colour map.
pub const DEFAULT_STD_DEV_SCALE: f64 = 0.2;
/// How long clients and shared caches may reuse a tile without asking;
/// after that they revalidate with `If-None-Match` (a 304 costs nothing).
const CACHE_CONTROL: &str = "public, max-age=300";

/// What a GET tile shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Aov {
    /// The rendered radiance.
    #[default]
    Radiance,
    /// The per-pixel standard error (module docs).
    StdDev,
    /// The tile's irradiance-cache records (module docs).
    Records,
}

/// Query parameters of a GET tile (module docs).
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TileQuery {
    /// Tile side in pixels, 1..=√`limits.max_tile_area`; default 64.
    pub size: Option<u32>,
    /// `draft`, `preview` (default), `interactive`, `standard` or `final`.
    #[param(value_type = Option<String>)]
    pub preset: Option<Preset>,
    /// Pass to show, 0-based (the mean of passes `0..=pass`); default the last.
    pub pass: Option<u32>,
    /// Seed of every random stream; default 1.
    pub seed: Option<u64>,
    /// PNG radiance only: exposure in stops; default 0.
    pub exposure: Option<f32>,
    /// `radiance` (default), `std_dev` or `records`.
    #[param(value_type = Option<String>)]
    pub aov: Option<Aov>,
    /// `std_dev` PNG only: relative standard error at the top of the colour map; default 0.2.
    pub scale: Option<f64>,
    /// Denoise the tile, each pixel with a calibrated standard error (docs/math.md §16.6, §16.7); default: as the preset does on the scene.
    pub denoise: Option<bool>,
}

/// The path of a GET tile: scene id, column and `{row}.{format}`.
pub struct TilePath {
    pub id: String,
    pub tx: u32,
    pub ty: u32,
    pub format: ImageEncoding,
}

impl<S: Send + Sync> FromRequestParts<S> for TilePath {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let Path((id, tx, file)) =
            Path::<(String, String, String)>::from_request_parts(parts, state).await?;
        let (ty, extension) = file.split_once('.').ok_or_else(|| {
            ApiError::invalid("format", "name the format: {ty}.png, {ty}.exr or {ty}.json")
        })?;
        let format = match extension {
            "png" => ImageEncoding::Png,
            "exr" => ImageEncoding::Exr,
            "json" => ImageEncoding::Json,
            other => {
                return Err(ApiError::invalid(
                    "format",
                    format!("{other:?} is not one of png, exr, json"),
                ));
            }
        };
        Ok(TilePath {
            id,
            tx: tile_index("tx", &tx)?,
            ty: tile_index("ty", ty)?,
            format,
        })
    }
}

/// The tile column or row `text` of the path, or a 422 naming `field`.
fn tile_index(field: &str, text: &str) -> Result<u32, ApiError> {
    match text.parse::<u32>() {
        Ok(index) => Ok(index),
        Err(_) => Err(ApiError::invalid(
            field,
            format!("{text:?} is not a tile index"),
        )),
    }
}

/// One tile of the camera image on a grid (module docs).
#[utoipa::path(get, path = "/v1/scenes/{id}/tiles/{tx}/{ty_format}", tag = "scenes",
    params(("id" = String, Path, description = "Scene id"),
           ("tx" = u32, Path, description = "Tile column (0 = left)"),
           ("ty_format" = String, Path, description = "Tile row and format, e.g. `2.png`, `0.exr`, `3.json`"),
           TileQuery),
    responses((status = 200, description = "The tile; headers ETag, Cache-Control, x-tile-x, x-tile-y, \
                x-rays, x-records-created, x-passes, x-std-dev-scale (std_dev PNG), Server-Timing",
               content((Vec<u8> = "image/png"), (Vec<u8> = "image/x-exr"), (Object = "application/json"))),
               (status = 304, description = "`If-None-Match` names the tile's ETag"),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid parameter (named in `field`)", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn get_tile(
    State(state): State<Arc<AppState>>,
    path: TilePath,
    ApiQuery(query): ApiQuery<TileQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let started = Instant::now();
    let scene = state.scene(&path.id).await?;
    let limits = &state.config.limits;
    let (width, height) = scene.transport.scene().camera.resolution();
    let size = query.size.unwrap_or(DEFAULT_TILE_SIZE);
    let max_side = (limits.max_tile_area as f64).sqrt().floor() as u32;
    if !(1..=max_side).contains(&size) {
        return Err(ApiError::invalid(
            "size",
            format!("{size} is not in 1..={max_side} (limits.max_tile_area)"),
        ));
    }
    let (columns, rows) = (width.div_ceil(size), height.div_ceil(size));
    for (field, index, count) in [("tx", path.tx, columns), ("ty", path.ty, rows)] {
        if index >= count {
            return Err(ApiError::invalid(
                field,
                format!(
                    "{index} is outside the image: {count} tiles of {size} pixels ({width}×{height})"
                ),
            ));
        }
    }
    let aov = query.aov.unwrap_or_default();
    let format = path.format;
    // Only the parameters that change the bytes are normalised into the ETag.
    let exposure = match (aov, format) {
        (Aov::Radiance, ImageEncoding::Png) => query.exposure.unwrap_or(0.0),
        _ => 0.0,
    };
    if !exposure.is_finite() || query.exposure.is_some_and(|e| !e.is_finite()) {
        return Err(ApiError::invalid(
            "exposure",
            "must be a finite number of stops",
        ));
    }
    let scale = match (aov, format) {
        (Aov::StdDev, ImageEncoding::Png) => query.scale.unwrap_or(DEFAULT_STD_DEV_SCALE),
        _ => DEFAULT_STD_DEV_SCALE,
    };
    if !(scale.is_finite() && scale > 0.0)
        || query.scale.is_some_and(|s| !(s.is_finite() && s > 0.0))
    {
        return Err(ApiError::invalid("scale", "must be a positive number"));
    }
    if aov == Aov::Records && format == ImageEncoding::Exr {
        return Err(ApiError::invalid(
            "format",
            "the records AOV is a PNG overlay or JSON, not EXR",
        ));
    }
    let (x, y) = (path.tx * size, path.ty * size);
    let params = TileParams {
        x,
        y,
        width: size.min(width - x),
        height: size.min(height - y),
        preset: query.preset.unwrap_or_default(),
        samples_per_pixel: None,
        pass: query.pass,
        max_depth: None,
        seed: query.seed.unwrap_or(1),
        estimator: IntegratorSpec::default(),
        denoise: query.denoise,
    };
    let job = tile_job(&params, scene.transport.scene(), limits)?;
    // Everything the bytes depend on, as canonical JSON.
    let shown = serde_json::json!({
        "request": job.request,
        "denoise": job.denoise,
        "aov": aov,
        "format": format,
        "exposure": exposure,
        "scale": scale,
    });
    let etag = entity_tag(&[
        env!("CARGO_PKG_VERSION"),
        &scene.transport.scene().digest.to_string(),
        &job.integrator.content_key(),
        &shown.to_string(),
    ]);
    let mut common = HeaderMap::new();
    common.insert(header::ETAG, etag.clone());
    common.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static(CACHE_CONTROL),
    );
    if if_none_match(&headers, &etag) {
        return Ok((StatusCode::NOT_MODIFIED, common).into_response());
    }
    check_work(&job, scene.transport.scene(), limits)?;
    let shared = state.clone();
    let (tile, body, views_count) = state
        .pool
        .run(move |cancel| {
            let tile = render_progressive(&shared, &scene, &job, cancel)?;
            let camera = &scene.transport.scene().camera;
            let (body, views_count) = match aov {
                Aov::Radiance => (tile.image.encode(format, ToneMap { exposure })?, 0),
                Aov::StdDev => {
                    let bytes = match format {
                        ImageEncoding::Png => tile.image.relative_std_error_png(scale)?,
                        _ => tile
                            .image
                            .std_dev()
                            .ok_or_else(|| ApiError::Internal {
                                message: "the tile has no variance".into(),
                            })?
                            .encode(format, ToneMap::default())?,
                    };
                    (bytes, 0)
                }
                Aov::Records => {
                    // The records placed at the tile's pixels, of the
                    // blocks that shaded it.
                    let r = &job.request;
                    let records: Vec<_> = tile
                        .records
                        .iter()
                        .flat_map(|b| b.records.iter().copied())
                        .collect();
                    let inside = |v: &RecordView| {
                        let [px, py] = v.pixel;
                        (f64::from(r.x)..f64::from(r.x + r.width)).contains(&px)
                            && (f64::from(r.y)..f64::from(r.y + r.height)).contains(&py)
                    };
                    let views: Vec<RecordView> = record_views(camera, &records)
                        .into_iter()
                        .filter(inside)
                        .collect();
                    let bytes = match format {
                        ImageEncoding::Png => png_io::encode_png8(
                            &record_overlay(&views, r.x, r.y, r.width, r.height),
                            r.width,
                            r.height,
                            true,
                        )?,
                        // A JSON value always serialises (its keys are strings).
                        _ => serde_json::to_vec(&serde_json::json!({
                            "x": r.x, "y": r.y, "width": r.width, "height": r.height,
                            "records": views,
                        }))
                        .expect("a JSON value serialises"),
                    };
                    (bytes, views.len())
                }
            };
            Ok::<_, ApiError>((tile, body, views_count))
        })
        .await??;
    ::metrics::counter!(RAYS_TRACED).increment(tile.rays);
    let mut response = (common, body).into_response();
    let h = response.headers_mut();
    tile_headers(h, format, &job, &tile);
    if aov == Aov::Records {
        h.insert(X_RECORDS, HeaderValue::from(views_count as u64));
    }
    if (aov, format) == (Aov::StdDev, ImageEncoding::Png) {
        h.insert(
            X_STD_DEV_SCALE,
            HeaderValue::from_str(&scale.to_string()).expect("a number is a valid header"),
        );
    }
    let millis = started.elapsed().as_secs_f64() * 1e3;
    if let Ok(timing) = HeaderValue::from_str(&format!("render;dur={millis:.1}")) {
        h.insert(SERVER_TIMING, timing);
    }
    Ok(response)
}

/// A strong entity tag: the first 128 bits of BLAKE3 over `parts`.
fn entity_tag(parts: &[&str]) -> HeaderValue {
    let mut hasher = blake3::Hasher::new();
    for part in parts {
        hasher.update(&(part.len() as u64).to_le_bytes());
        hasher.update(part.as_bytes());
    }
    let hex = hasher.finalize().to_hex();
    HeaderValue::from_str(&format!("\"{}\"", &hex[..32])).expect("hex is a valid header")
}

/// Whether `If-None-Match` names `etag` (or is `*`); weak comparison, as
/// RFC 9110 §13.1.2 asks for this header.
fn if_none_match(headers: &HeaderMap, etag: &HeaderValue) -> bool {
    let Some(etag) = etag.to_str().ok() else {
        return false;
    };
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .map(|t| t.trim().trim_start_matches("W/"))
        .any(|t| t == "*" || t == etag)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_lists_and_weak_tags() {
        let tag = HeaderValue::from_static("\"abc\"");
        let with = |value: &'static str| {
            let mut h = HeaderMap::new();
            h.insert(header::IF_NONE_MATCH, HeaderValue::from_static(value));
            if_none_match(&h, &tag)
        };
        assert!(with("\"abc\""));
        assert!(with("\"x\", W/\"abc\""));
        assert!(with("*"));
        assert!(!with("\"abcd\""));
        assert!(!if_none_match(&HeaderMap::new(), &tag));
        assert_ne!(entity_tag(&["a", "bc"]), entity_tag(&["ab", "c"]));
    }
}
