//! Tiles of the camera image shaded through the irradiance cache
//! ([`crate::render::ShadingMethod::IrradianceCache`]).
//!
//! Two passes (see `placement`):
//! 1. **Placement** at the first hits of the rays through the tile's pixel
//!    centres (no random numbers), coarse to fine: pixels whose coordinates
//!    are multiples of 16 first, then 8, 4, 2, 1, so a batch's points are
//!    spread over the tile and rarely duplicate each other's records. Each
//!    point carries its pixel footprint: the distance to the camera times the
//!    angle between neighbouring pixel-centre rays (the footprint
//!    perpendicular to the ray), which bounds the record's radius between
//!    `min_pixels` and `max_pixels` of it.
//! 2. **Shading** by the shared pixel loop ([`render_tile_with`]): each
//!    jittered camera ray's first hit is shaded by
//!    [`Transport::outgoing_radiance`] with [`OnMiss::PathTrace`], so the pass
//!    only reads the cache.
//!
//! With `reproducible`, both passes use a private cache (same configuration
//! as the shared one), so the tile is bit-identical whatever the thread
//! count or the shared cache's content; the private records that the shared
//! cache does not already cover are then published to it. Otherwise records
//! are placed in and read from the shared cache: a second request for the
//! same tile finds them and traces only camera, shadow and fallback rays.

use std::sync::Mutex;

use rand::Rng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::irradiance_cache::IrradianceCache;
use super::placement::{PlacementPoint, PlacementReport, place_records};
use super::record::PixelFootprint;
use super::shading::{CachedShading, OnMiss, ShadingStats, cache_to_render, indirect_paths};
use crate::render::lights::environment_radiance;
use crate::render::tile::{
    CameraRayShader, RenderedTile, TileRequest, pixel_rng, render_tile_with,
};
use crate::render::{QueryPoint, RenderError, Rgb, TraceStats, Transport};
use crate::scene::Ray;

/// What a cached tile request did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CachedTileReport {
    /// Pixel-centre hits considered for records.
    pub placement_points: u64,
    /// Records placed (in the private cache when reproducible).
    pub placement: PlacementReport,
    /// The shading pass's counters (camera rays included in `rays`).
    pub shading: ShadingStats,
    /// Records copied from the private cache into the shared one.
    pub records_published: u64,
}

/// Shades camera rays through a cache (module docs), collecting counters
/// and the first error (the pixel loop's shader interface cannot fail).
struct CacheRayShader<'a> {
    transport: &'a Transport,
    cache: &'a IrradianceCache,
    shading: &'a CachedShading,
    /// Segments counted from the first hit.
    depth: u32,
    stats: Mutex<ShadingStats>,
    error: Mutex<Option<RenderError>>,
}

impl CameraRayShader for CacheRayShader<'_> {
    fn radiance(&self, ray: Ray, rng: &mut Pcg64, stats: &mut TraceStats) -> Rgb {
        let scene = self.transport.scene();
        stats.rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            return environment_radiance(scene, ray.dir);
        };
        let mut local = ShadingStats::default();
        let result = self.transport.outgoing_radiance(
            &hit,
            -ray.dir,
            self.cache,
            self.shading,
            self.depth,
            OnMiss::PathTrace,
            None,
            rng,
            &mut local,
        );
        stats.rays += local.rays;
        *self.stats.lock().unwrap_or_else(|e| e.into_inner()) += local;
        result.unwrap_or_else(|e| {
            self.error
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .get_or_insert(e);
            Rgb::BLACK
        })
    }
}

/// Pixels of the tile, coarsest level first (module docs), row-major within a level.
fn coarse_to_fine(request: &TileRequest) -> Vec<(u32, u32)> {
    let level = |px: u32, py: u32| (px | py | 16).trailing_zeros();
    let mut pixels: Vec<(u32, u32)> = (request.y..request.y + request.height)
        .flat_map(|py| (request.x..request.x + request.width).map(move |px| (px, py)))
        .collect();
    // Stable: row-major order is kept within a level.
    pixels.sort_by_key(|&(px, py)| std::cmp::Reverse(level(px, py)));
    pixels
}

impl Transport {
    /// Placement points of a tile (module docs): front-facing first hits
    /// with a diffuse lobe, in coarse-to-fine order.
    fn placement_points(
        &self,
        request: &TileRequest,
        shading: &CachedShading,
    ) -> Result<Vec<PlacementPoint>, RenderError> {
        let scene = self.scene();
        let camera = &scene.camera;
        let options = &shading.options;
        coarse_to_fine(request)
            .par_iter()
            .map(|&(px, py)| {
                let (cx, cy) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
                let ray = camera.generate_ray(cx, cy);
                let Some(hit) = scene.intersect(&ray) else {
                    return Ok(None);
                };
                let diffuse = self
                    .bsdf(hit.material)
                    .is_some_and(|b| !b.diffuse.is_black());
                if !diffuse || hit.shading_normal.dot(ray.dir) >= 0.0 {
                    return Ok(None);
                }
                let next = camera.generate_ray(cx + 1.0, cy);
                let angle = ray.dir.angle_between(next.dir);
                let size = (hit.t * angle).max(f64::MIN_POSITIVE);
                let footprint = PixelFootprint::new(size, options.min_pixels, options.max_pixels)
                    .map_err(cache_to_render)?;
                Ok(Some(PlacementPoint {
                    point: QueryPoint::new(hit.position, hit.shading_normal)?,
                    footprint: Some(footprint),
                }))
            })
            .filter_map(Result::transpose)
            .collect()
    }

    /// Renders one tile through the irradiance cache `cache` (module docs).
    /// `cache` must belong to this scene, `shading.rule` and the request's
    /// `max_depth` (the caller keys its caches by them); the request's
    /// `method` is not consulted.
    pub fn render_tile_cached(
        &self,
        request: &TileRequest,
        cache: &IrradianceCache,
        shading: &CachedShading,
    ) -> Result<(RenderedTile, CachedTileReport), RenderError> {
        let camera = &self.scene().camera;
        request.validate(camera.resolution())?;
        shading.options.validate().map_err(cache_to_render)?;
        let depth = request.max_depth - 1;
        let mut report = CachedTileReport::default();
        let private;
        let target = if shading.options.reproducible {
            private = IrradianceCache::new(*cache.config()).map_err(cache_to_render)?;
            &private
        } else {
            cache
        };
        if depth >= 2 {
            let points = self.placement_points(request, shading)?;
            report.placement_points = points.len() as u64;
            // The tile's own stream family, so tiles sharing a seed do not
            // reuse each other's record rotations.
            let seed = pixel_rng(request.seed, request.x, request.y).next_u64();
            let options = shading
                .options
                .placement(indirect_paths(depth), seed)
                .map_err(cache_to_render)?;
            report.placement = place_records(target, self, &shading.rule, &points, &options)
                .map_err(cache_to_render)?;
        }
        let shader = CacheRayShader {
            transport: self,
            cache: target,
            shading,
            depth,
            stats: Mutex::new(ShadingStats::default()),
            error: Mutex::new(None),
        };
        let mut tile = render_tile_with(camera, &shader, request)?;
        if let Some(e) = shader.error.into_inner().unwrap_or_else(|p| p.into_inner()) {
            return Err(e);
        }
        report.shading = shader.stats.into_inner().unwrap_or_else(|p| p.into_inner());
        report.shading.rays = tile.rays;
        tile.rays += report.placement.rays;
        if shading.options.reproducible {
            report.records_published = publish(&target.records(), cache, shading)?;
        }
        Ok((tile, report))
    }
}

/// Inserts the records `cache` does not already cover at their own
/// positions; returns how many.
fn publish(
    records: &[super::Record],
    cache: &IrradianceCache,
    shading: &CachedShading,
) -> Result<u64, RenderError> {
    let accuracy = shading.options.validate().map_err(cache_to_render)?;
    let mut published = 0;
    for r in records {
        let point = QueryPoint::new(r.position, r.normal)?;
        if cache.lookup(&point, accuracy).is_none() {
            cache.insert(*r).map_err(cache_to_render)?;
            published += 1;
        }
    }
    Ok(published)
}
