//! The headers of a tile response, as both tile routes send them and CORS
//! exposes them: each name written once here.

use axum::http::{HeaderMap, HeaderName, HeaderValue, header};

use crate::image::ImageEncoding;
use crate::integrator::progressive::{ProgressiveTile, TileJob};

/// Column of the tile's left edge, pixels.
pub const X_TILE_X: HeaderName = HeaderName::from_static("x-tile-x");
/// Row of the tile's top edge, pixels.
pub const X_TILE_Y: HeaderName = HeaderName::from_static("x-tile-y");
/// Rays this request traced (memoised parts cost none).
pub const X_RAYS: HeaderName = HeaderName::from_static("x-rays");
/// Records this request placed.
pub const X_RECORDS_CREATED: HeaderName = HeaderName::from_static("x-records-created");
/// Diffuse shading points served by records, over the passes.
pub const X_CACHE_HITS: HeaderName = HeaderName::from_static("x-cache-hits");
/// Passes of the tile's preset (1 with explicit samples per pixel).
pub const X_PASSES: HeaderName = HeaderName::from_static("x-passes");
/// Passes this request rendered (the rest were memoised).
pub const X_PASSES_RENDERED: HeaderName = HeaderName::from_static("x-passes-rendered");
/// 1 if the tile was denoised (asked for, or the preset's choice on the
/// scene), else 0.
pub const X_DENOISED: HeaderName = HeaderName::from_static("x-denoised");
/// Records shown by a `records` AOV.
pub const X_RECORDS: HeaderName = HeaderName::from_static("x-records");
/// The relative standard error at the top of a `std_dev` PNG's colour map.
pub const X_STD_DEV_SCALE: HeaderName = HeaderName::from_static("x-std-dev-scale");
/// How long the render took, for browsers' timing panels.
pub const SERVER_TIMING: HeaderName = HeaderName::from_static("server-timing");

/// Every header a tile response may carry beyond the standard ones, for
/// pages of other origins to read (CORS `Access-Control-Expose-Headers`).
pub const EXPOSED: [HeaderName; 12] = [
    header::ETAG,
    SERVER_TIMING,
    X_TILE_X,
    X_TILE_Y,
    X_RAYS,
    X_RECORDS_CREATED,
    X_RECORDS,
    X_CACHE_HITS,
    X_PASSES,
    X_PASSES_RENDERED,
    X_DENOISED,
    X_STD_DEV_SCALE,
];

/// Sets the headers every tile response carries: its content type, where
/// it lies and what rendering it took.
pub fn tile_headers(
    headers: &mut HeaderMap,
    format: ImageEncoding,
    job: &TileJob,
    tile: &ProgressiveTile,
) {
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(format.content_type()),
    );
    let r = &job.request;
    for (name, n) in [
        (X_TILE_X, u64::from(r.x)),
        (X_TILE_Y, u64::from(r.y)),
        (X_RAYS, tile.rays),
        (X_RECORDS_CREATED, tile.records_created),
        (X_CACHE_HITS, tile.cache_hits),
        (X_PASSES, u64::from(job.request.passes)),
        (X_PASSES_RENDERED, u64::from(tile.passes_rendered)),
        (X_DENOISED, u64::from(job.denoise)),
    ] {
        headers.insert(name, HeaderValue::from(n));
    }
}
