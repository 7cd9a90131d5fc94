//! Tiles of the camera image shaded through the irradiance cache
//! (the `cache` method of an integrator spec).
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
//!    [`CachedIntegrator::outgoing_radiance`] with [`OnMiss::PathTrace`], so the pass
//!    only reads the cache.
//!
//! With `reproducible`, both passes use a private cache (same configuration
//! as the shared one), so the tile is bit-identical whatever the thread
//! count or the shared cache's content; the private records that the shared
//! cache does not already cover are then published to it. Otherwise records
//! are placed in and read from the shared cache: a second request for the
//! same tile finds them and traces only camera, shadow and fallback rays.
//!
//! # Record blocks: no tile seams
//! A tile shaded only by its own records shows its edges: pixels on either
//! side of a boundary interpolate different, independently noisy records.
//! Progressive tiles (`integrator::progressive`: presets, GET tiles,
//! `render --preset`) therefore place records per **block** of a fixed grid
//! of the image ([`RECORD_BLOCK`] pixels, aligned to its top-left corner),
//! each block's records a function of the block alone ([`CachedIntegrator::tile_records`]
//! of its rectangle), and shade a tile with the records of every block
//! within [`block_margin`] blocks of it ([`CachedIntegrator::record_blocks`],
//! [`CachedIntegrator::render_tile_from_blocks`]). A record reaches at most `max_pixels`
//! footprints from its point, so every record that covers a pixel comes
//! from a block the pixel's tile includes, whatever the tiling: the image
//! does not depend on how it is cut into tiles, and tiles share the cost of
//! the blocks they have in common. (Lookups at points reached through a
//! mirror or glass chain, or by a glossy lobe's samples, may lie outside
//! the tile's blocks: there no record covers them and they are path
//! traced, so those pixels still depend on the tiling, without bias.)

use std::sync::Mutex;

use rand::Rng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::config::indirect_paths;
use super::dense::probe;
use super::placement::{PlacementCache, PlacementReport, place_records};
use super::record_estimate::{PlacementPoint, diffuse_front};
use super::secondary::secondary_cache_of;
use super::shade::{CachedIntegrator, Gather};
use super::shade_point::{OnMiss, ShadePoint};
use super::stats::ShadingStats;
use crate::cache::{CacheConfig, IrradianceCache, PixelFootprint, Record};
use crate::render::lights::environment_radiance;
use crate::render::{
    CameraRayShader, Cancel, Evaluation, PathDepth, PixelSample, QueryPoint, RenderError,
    RenderedTile, Rgb, SamplePlan, TileRequest, TraceStats, pixel_rng, render_tile_with,
};
use crate::scene::{Ray, Scene};

/// What a cached tile request did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CachedTileReport {
    /// Pixel-centre hits considered for records.
    pub placement_points: u64,
    /// Records placed (in the private cache when reproducible).
    pub placement: PlacementReport,
    /// Records of the scene's secondary cache, if this request built it
    /// (`secondary`).
    pub secondary: PlacementReport,
    /// The shading pass's counters (camera rays included in `rays`).
    pub shading: ShadingStats,
    /// Records copied from the private cache into the shared one.
    pub records_published: u64,
    /// Tiles that placed no records as the probe found them too dense
    /// (`dense`; 0 or 1 per tile), and the probe's rays (in
    /// `placement.rays` too).
    pub dense_tiles: u64,
    pub probe_rays: u64,
}

impl CachedTileReport {
    /// Whether the tile (one) placed no records as they would not pay.
    pub fn dense(&self) -> bool {
        self.dense_tiles > 0
    }

    /// Adds `other`'s counts (of another tile of the same image).
    pub fn add(&mut self, other: &CachedTileReport) {
        self.placement_points += other.placement_points;
        self.placement.records_created += other.placement.records_created;
        self.placement.ambient_records += other.placement.ambient_records;
        self.placement.rays += other.placement.rays;
        self.placement.fallbacks += other.placement.fallbacks;
        self.secondary.records_created += other.secondary.records_created;
        self.secondary.rays += other.secondary.rays;
        self.shading += other.shading;
        self.records_published += other.records_published;
        self.dense_tiles += other.dense_tiles;
        self.probe_rays += other.probe_rays;
    }
}

/// Side of the blocks reproducible records are placed in, pixels: the
/// tile size of GET tiles, so an aligned tile is one block (module docs).
pub const RECORD_BLOCK: u32 = 64;

/// How far from its placement point, in image pixels, a record may reach
/// per pixel footprint of its radius: 1 where the surface faces the
/// camera, more where the covered points lie nearer the camera than the
/// record (their footprints are smaller). For a radius of `m` footprints
/// at distance `t`, a point up to `m·f` nearer has a footprint at least
/// `(t − m·f)/t` of the record's, so the reach is at most `m·t/(t − m·f)`
/// pixels: 1.13 `m` for `m = 40` at a 0.16° pixel (256 pixels over 40°);
/// 1.25 leaves room for wider pixels.
const BLOCK_REACH: f64 = 1.25;

/// Blocks on each side of a tile whose records may cover its pixels, for
/// records of at most `max_pixels` footprints (module docs).
pub fn block_margin(max_pixels: f64) -> u32 {
    (BLOCK_REACH * max_pixels / f64::from(RECORD_BLOCK)).ceil() as u32
}

/// The blocks within `margin` blocks of `request`'s rectangle, clipped to
/// an image of `resolution`, row-major: each a request for the block's
/// rectangle with `request`'s depth and seed (what its records depend on).
pub fn record_blocks(
    request: &TileRequest,
    margin: u32,
    resolution: (u32, u32),
) -> Vec<TileRequest> {
    let b = RECORD_BLOCK;
    let last = |start: u32, size: u32, image: u32| {
        ((start + size.max(1) - 1) / b + margin).min(image.max(1).div_ceil(b) - 1)
    };
    let (x1, y1) = (
        last(request.x, request.width, resolution.0),
        last(request.y, request.height, resolution.1),
    );
    let (x0, y0) = (
        (request.x / b).saturating_sub(margin),
        (request.y / b).saturating_sub(margin),
    );
    (y0..=y1)
        .flat_map(|by| (x0..=x1).map(move |bx| (bx, by)))
        .map(|(bx, by)| TileRequest {
            x: bx * b,
            y: by * b,
            width: b.min(resolution.0 - bx * b),
            height: b.min(resolution.1 - by * b),
            ..*request
        })
        .collect()
}

/// One block's records (module docs), as a tile shades with them.
#[derive(Clone, Copy, Debug)]
pub struct RecordBlock<'a> {
    /// The block's rectangle: x, y, width, height in pixels.
    pub rect: [u32; 4],
    /// Its records, in placement order.
    pub records: &'a [Record],
    /// The block placed none as its probe found it too dense
    /// ([`CachedTileReport::dense`]): its pixels take the dense shading.
    pub dense: bool,
}

/// Shades camera rays through a cache (module docs), collecting counters
/// and the first error (the pixel loop's shader interface cannot fail).
struct CacheRayShader<'a> {
    integrator: CachedIntegrator<'a>,
    /// The request's depth, counted from the camera.
    depth: PathDepth,
    /// Rectangles (x, y, width, height) whose pixels placed no records
    /// (`dense`).
    dense: Vec<[u32; 4]>,
    stats: Mutex<ShadingStats>,
    error: Mutex<Option<RenderError>>,
}

impl CameraRayShader for CacheRayShader<'_> {
    fn scene(&self) -> &Scene {
        self.integrator.transport.scene()
    }

    fn radiance(
        &self,
        ray: Ray,
        sample: PixelSample,
        rng: &mut Pcg64,
        stats: &mut TraceStats,
    ) -> Evaluation {
        let scene = self.integrator.transport.scene();
        stats.rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            return Evaluation::of(environment_radiance(scene, ray.dir));
        };
        let mut local = ShadingStats::default();
        let [px, py] = sample.pixel;
        let dense = self
            .dense
            .iter()
            .any(|&[x, y, w, h]| (x..x + w).contains(&px) && (y..y + h).contains(&py));
        let how = ShadePoint {
            max_depth: self.depth,
            on_miss: OnMiss::PathTrace,
            sample: Some(sample),
            dense,
        };
        let result = self
            .integrator
            .outgoing_radiance(&hit, -ray.dir, how, rng, &mut local);
        stats.rays += local.rays;
        *self.stats.lock().unwrap_or_else(|e| e.into_inner()) += local;
        result.unwrap_or_else(|e| {
            self.error
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .get_or_insert(e);
            Evaluation::of(Rgb::BLACK)
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

impl CachedIntegrator<'_> {
    /// Placement points of a tile (module docs): front-facing first hits
    /// with a diffuse lobe, in coarse-to-fine order.
    fn placement_points(&self, request: &TileRequest) -> Result<Vec<PlacementPoint>, RenderError> {
        let scene = self.transport.scene();
        let camera = &scene.camera;
        let options = &self.shading.options;
        coarse_to_fine(request)
            .par_iter()
            .map(|&(px, py)| {
                let (cx, cy) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
                let ray = camera.generate_ray(cx, cy);
                let Some(hit) = scene.intersect(&ray) else {
                    return Ok(None);
                };
                if !diffuse_front(self.transport, &hit, ray.dir) {
                    return Ok(None);
                }
                let size = camera.span_at(cx, cy, 1.0, hit.t).max(f64::MIN_POSITIVE);
                let footprint = PixelFootprint::new(size, options.min_pixels, options.max_pixels)?;
                Ok(Some(PlacementPoint {
                    point: QueryPoint::new(hit.position, hit.shading_normal)?,
                    footprint: Some(footprint),
                }))
            })
            .filter_map(Result::transpose)
            .collect()
    }

    /// Renders one tile through this integrator's cache (module docs). The
    /// cache must belong to this scene, the shading's rule and the request's
    /// `max_depth` (the caller keys its caches by them); the request's
    /// `method` is not consulted. Stops between records and pixels once
    /// `cancel` is set.
    /// `plan`: the rays per pixel of an adaptive pass ([`render_tile_with`]).
    pub fn render_tile(
        &self,
        request: &TileRequest,
        plan: Option<&SamplePlan>,
        cancel: &Cancel,
    ) -> Result<(RenderedTile, CachedTileReport), RenderError> {
        if !self.shading.options.reproducible {
            let mut report =
                self.place_tile_records(request, |c| PlacementCache::Shared(c), cancel)?;
            let dense = own_rect_if(request, report.dense());
            let (tile, shading) = self.shade_tile(request, plan, dense, cancel)?;
            report.shading = shading;
            return Ok((add_placement_rays(tile, &report), report));
        }
        let (records, mut report) = self.tile_records(request, cancel)?;
        let block = RecordBlock {
            rect: [request.x, request.y, request.width, request.height],
            records: &records,
            dense: report.dense(),
        };
        let (tile, shading) = self.render_tile_from_blocks(request, plan, &[block], cancel)?;
        report.shading = shading;
        report.records_published = self.publish(&records)?;
        Ok((add_placement_rays(tile, &report), report))
    }

    /// The records a reproducible tile places (module docs): a function of
    /// the scene, this integrator's configuration and the request's
    /// rectangle, `max_depth` and `seed` only — not of its pass or samples
    /// per pixel, the thread count or the shared cache — in insertion order.
    /// A caller may keep them and shade any pass of the tile with
    /// [`Self::render_tile_from_blocks`] without placing them again.
    pub fn tile_records(
        &self,
        request: &TileRequest,
        cancel: &Cancel,
    ) -> Result<(Vec<Record>, CachedTileReport), RenderError> {
        let private = self.private_cache()?;
        let integrator = CachedIntegrator {
            cache: &private,
            ..*self
        };
        let report =
            integrator.place_tile_records(request, |c| PlacementCache::Private(c), cancel)?;
        Ok((private.records(), report))
    }

    /// The blocks whose records shade `request` in a progressive tile
    /// (module docs), row-major.
    pub fn record_blocks(&self, request: &TileRequest) -> Vec<TileRequest> {
        let margin = block_margin(self.shading.options.max_pixels);
        record_blocks(request, margin, self.transport.scene().camera.resolution())
    }

    /// One tile shaded through a private cache holding exactly the records
    /// of `blocks` (each as [`Self::tile_records`] returns them, the blocks
    /// in a fixed order), so the result is bit-identical whatever ran
    /// before; returns the tile (camera and shading rays only) and the
    /// shading counters. The records are taken as placed: their radii were
    /// clamped against their own block's neighbours, not again here, so a
    /// record shades alike in every tile that includes its block.
    pub fn render_tile_from_blocks(
        &self,
        request: &TileRequest,
        plan: Option<&SamplePlan>,
        blocks: &[RecordBlock],
        cancel: &Cancel,
    ) -> Result<(RenderedTile, ShadingStats), RenderError> {
        let private = IrradianceCache::new(CacheConfig {
            neighbour_clamp: false,
            ..*self.cache.config()
        })?;
        let records = blocks.iter().flat_map(|b| b.records);
        for (i, record) in records.enumerate() {
            if i % 256 == 0 {
                cancel.check()?;
            }
            private.insert(*record)?;
        }
        let dense = blocks.iter().filter(|b| b.dense).map(|b| b.rect).collect();
        CachedIntegrator {
            cache: &private,
            ..*self
        }
        .shade_tile(request, plan, dense, cancel)
    }

    /// Inserts into this integrator's cache the records it does not
    /// already cover at their own positions; returns how many.
    pub fn publish(&self, records: &[Record]) -> Result<u64, RenderError> {
        let accuracy = self.shading.accuracy();
        let mut published = 0;
        for r in records {
            let point = QueryPoint::new(r.position, r.normal)?;
            if self.cache.lookup(&point, accuracy).is_none() {
                self.cache.insert(*r)?;
                published += 1;
            }
        }
        Ok(published)
    }

    /// An empty cache configured as the shared one.
    fn private_cache(&self) -> Result<IrradianceCache, RenderError> {
        Ok(IrradianceCache::new(*self.cache.config())?)
    }

    /// The placement pass (module docs) into this integrator's cache, with
    /// `readers` saying who reads it meanwhile.
    fn place_tile_records(
        &self,
        request: &TileRequest,
        readers: fn(&IrradianceCache) -> PlacementCache<'_>,
        cancel: &Cancel,
    ) -> Result<CachedTileReport, RenderError> {
        let (transport, shading) = (self.transport, self.shading);
        request.validate(transport.scene().camera.resolution())?;
        let mut report = CachedTileReport::default();
        // Records serve the indirect light of the camera rays' first hits,
        // whose paths count their segments from the hit.
        let Some(from_hit) = request
            .max_depth
            .after_first_segment()
            .filter(|d| d.has_reflections())
        else {
            return Ok(report);
        };
        let points = self.placement_points(request)?;
        report.placement_points = points.len() as u64;
        // The tile's own stream family, so tiles sharing a seed do not
        // reuse each other's record rotations.
        let seed = pixel_rng(request.seed, request.x, request.y).next_u64();
        let options = shading.placement(indirect_paths(from_hit), seed);
        if let Some(limit) = shading.options.max_records_per_pixel {
            let config = *self.cache.config();
            let found = probe(
                transport,
                config,
                shading.rule.spec().samples,
                &points,
                &options,
                cancel,
            )?;
            report.probe_rays = found.rays;
            report.placement.rays += found.rays;
            if found.is_dense(points.len(), limit) {
                report.dense_tiles = 1;
                return Ok(report);
            }
        }
        // A private cache is only read at the bounces, so the batch stays
        // deterministic (see `placement`).
        let reproducible = shading.options.reproducible;
        let (secondary, built) = secondary_cache_of(self, options.paths, cancel)?;
        report.secondary = built;
        let integrator = CachedIntegrator {
            secondary: secondary.as_ref().map(|s| &s.cache),
            ..*self
        };
        let gather = Gather::for_record(integrator, options.paths, 0, !reproducible);
        report.placement = place_records(
            readers(self.cache),
            transport,
            &shading.rule,
            &points,
            &options,
            gather,
            cancel,
        )?;
        Ok(report)
    }

    /// The shading pass (module docs): reads this integrator's cache only.
    fn shade_tile(
        &self,
        request: &TileRequest,
        plan: Option<&SamplePlan>,
        dense: Vec<[u32; 4]>,
        cancel: &Cancel,
    ) -> Result<(RenderedTile, ShadingStats), RenderError> {
        let camera = &self.transport.scene().camera;
        let shader = CacheRayShader {
            integrator: *self,
            depth: request.max_depth,
            dense,
            stats: Mutex::new(ShadingStats::default()),
            error: Mutex::new(None),
        };
        let tile = render_tile_with(camera, &shader, request, plan, cancel)?;
        if let Some(e) = shader.error.into_inner().unwrap_or_else(|p| p.into_inner()) {
            return Err(e);
        }
        let mut stats = shader.stats.into_inner().unwrap_or_else(|p| p.into_inner());
        stats.rays = tile.rays;
        Ok((tile, stats))
    }
}

/// `request`'s rectangle if `dense`, for [`CacheRayShader::dense`].
fn own_rect_if(request: &TileRequest, dense: bool) -> Vec<[u32; 4]> {
    match dense {
        true => vec![[request.x, request.y, request.width, request.height]],
        false => Vec::new(),
    }
}

/// The tile's rays with its placement's added.
fn add_placement_rays(mut tile: RenderedTile, report: &CachedTileReport) -> RenderedTile {
    tile.rays += report.placement.rays + report.secondary.rays;
    tile
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    use super::super::dense::MIN_DENSE_RECORDS;
    use crate::bmc::cache::QuadratureCache;
    use crate::cache::CacheConfig;
    use crate::image::relative_rmse;
    use crate::integrator::cached::{CacheShadingOptions, CachedShading, default_rule_spec};
    use crate::render::Transport;
    use crate::render::tile::tests::request;
    use crate::testing::{cornell, in_pool};

    /// A small, fast configuration: 16 directions per record.
    fn shading(options: CacheShadingOptions) -> CachedShading {
        let mut spec = default_rule_spec();
        spec.samples.count = 16;
        CachedShading::new(spec, 4, Arc::new(QuadratureCache::new(1 << 24)), options).unwrap()
    }

    fn options(reproducible: bool) -> CacheShadingOptions {
        CacheShadingOptions {
            reproducible,
            light_samples: 2,
            ..CacheShadingOptions::default()
        }
    }

    fn cache() -> IrradianceCache {
        IrradianceCache::new(CacheConfig::default()).unwrap()
    }

    fn cached_request(x: u32, y: u32, side: u32) -> TileRequest {
        TileRequest {
            max_depth: PathDepth::constant(5),
            ..request(x, y, side, side)
        }
    }

    fn render_cached(
        transport: &Transport,
        request: &TileRequest,
        cache: &IrradianceCache,
        shading: &CachedShading,
    ) -> Result<(RenderedTile, CachedTileReport), RenderError> {
        CachedIntegrator::new(transport, cache, shading).render_tile(
            request,
            None,
            &Cancel::never(),
        )
    }

    #[test]
    fn reproducible_tiles_ignore_threads_and_prior_cache_content() {
        let transport = cornell(16);
        let (quiet, busy) = (cache(), cache());
        let r = cached_request(0, 0, 16);
        // Fill `busy` with other records first: another seed, shared mode.
        let other = TileRequest { seed: 99, ..r };
        render_cached(&transport, &other, &busy, &shading(options(false))).unwrap();
        let before = busy.stats().records;
        assert!(before > 0);
        let s = shading(options(true));
        let (a, ra) = in_pool(1, || render_cached(&transport, &r, &quiet, &s)).unwrap();
        let (b, rb) = in_pool(2, || render_cached(&transport, &r, &busy, &s)).unwrap();
        assert_eq!(a, b);
        assert_eq!(ra.placement, rb.placement);
        assert!(ra.placement.records_created > 0);
        // Publishing skips records already covered: in the empty cache only
        // by records published before them (same-batch neighbours).
        assert!(ra.records_published > 0);
        assert!(ra.records_published <= ra.placement.records_created);
        assert_eq!(quiet.stats().records, ra.records_published);
        assert_eq!(busy.stats().records, before + rb.records_published);
        assert!(rb.records_published < ra.records_published);
        // And the method is not a no-op: light arrives, the seed matters.
        assert!(a.image.rgb().iter().any(|p| p[0] > 0.0));
        let (c, _) =
            render_cached(&transport, &TileRequest { seed: 8, ..r }, &cache(), &s).unwrap();
        assert_ne!(c.image, a.image);
    }

    #[test]
    fn a_second_request_reuses_the_shared_cache() {
        let transport = cornell(16);
        let shared = cache();
        let s = shading(options(false));
        let r = cached_request(0, 0, 16);
        let (first, r1) = render_cached(&transport, &r, &shared, &s).unwrap();
        let (second, r2) = render_cached(&transport, &r, &shared, &s).unwrap();
        assert!(r1.placement.records_created > 0);
        assert_eq!(r2.placement.records_created, 0);
        assert_eq!(shared.stats().records, r1.placement.records_created);
        // Same records, same pixel streams: the same image for fewer rays.
        assert_eq!(first.image, second.image);
        assert!(
            2 * second.rays < first.rays,
            "{} vs {}",
            second.rays,
            first.rays
        );
    }

    /// 8 clients render tiles concurrently into one cache: every record
    /// a request created is stored once (no evictions at this budget).
    #[test]
    fn concurrent_tile_requests_keep_the_cache_consistent() {
        let transport = cornell(32);
        let shared = cache();
        let s = shading(options(false));
        let created: Vec<u64> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..8u32)
                .map(|i| {
                    let (transport, shared, s) = (&transport, &shared, &s);
                    scope.spawn(move || {
                        let r = cached_request((i % 4) * 8, (i / 4) * 16, 8);
                        let (_, report) = render_cached(transport, &r, shared, s).unwrap();
                        report.placement.records_created
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let stats = shared.stats();
        let total: u64 = created.iter().sum();
        assert!(total > 0);
        assert_eq!(stats.inserts, total);
        assert_eq!(stats.records, total);
        assert_eq!(stats.evictions, 0);
        assert_eq!(stats.hits + stats.misses, stats.lookups);
        let records = shared.records();
        assert_eq!(records.len() as u64, total);
        let a = crate::cache::Accuracy::new(0.5).unwrap();
        for r in &records {
            let p = QueryPoint::new(r.position, r.normal).unwrap();
            assert!(shared.lookup(&p, a).is_some());
        }
    }

    /// The cached image agrees with path tracing on the diffuse pixels
    /// (emitter pixels masked) within the two images' noise plus a small
    /// interpolation bias; a missing π or albedo would be off by ≥ 30 %.
    #[test]
    fn cached_tiles_agree_with_path_tracing() {
        let transport = cornell(16);
        let s = shading(CacheShadingOptions {
            light_samples: 16,
            ..options(true)
        });
        let r = TileRequest {
            samples_per_pixel: 4,
            ..cached_request(0, 0, 16)
        };
        let (cached, _) = render_cached(&transport, &r, &cache(), &s).unwrap();
        assert_agrees_with_path_tracing(&transport, &cached, &r);
    }

    /// Asserts that `cached`, rendered for `r`, agrees with a 256-spp path
    /// traced tile (see [`cached_tiles_agree_with_path_tracing`]).
    fn assert_agrees_with_path_tracing(
        transport: &Transport,
        cached: &RenderedTile,
        r: &TileRequest,
    ) {
        let traced = crate::integrator::PathIntegrator::new(transport)
            .render_tile(
                &TileRequest {
                    samples_per_pixel: 256,
                    ..*r
                },
                None,
                &Cancel::never(),
            )
            .unwrap();
        let mask: Vec<bool> = traced
            .image
            .rgb()
            .iter()
            .map(|p| p.iter().all(|&c| c < 1.0))
            .collect();
        let e = relative_rmse(&cached.image, &traced.image, Some(&mask)).unwrap();
        let noise_traced = relative_rmse(&traced.image, &traced.image, Some(&mask))
            .unwrap()
            .expected_from_variance
            .unwrap();
        let noise_cached = e.expected_from_variance.unwrap();
        let expected = (noise_traced.powi(2) + noise_cached.powi(2)).sqrt();
        assert!(
            e.overall < 1.5 * expected + 0.05,
            "{} vs noise {expected}",
            e.overall
        );
        // Means over the diffuse pixels.
        let mean = |img: &crate::image::Image| -> f64 {
            img.rgb()
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .map(|(p, _)| p.iter().map(|&c| f64::from(c)).sum::<f64>())
                .sum()
        };
        let ratio = mean(&cached.image) / mean(&traced.image);
        assert!((ratio - 1.0).abs() < 0.05, "{ratio}");
    }

    /// Records that read the scene's secondary cache: the request that
    /// builds it reports its records, later ones find it built; a tile is
    /// the same bytes whichever request built the cache and on however many
    /// threads; its records differ from path-gathered ones, and its image
    /// agrees with path tracing.
    #[test]
    fn secondary_cache_tiles_are_reproducible_and_agree_with_path_tracing() {
        let transport = cornell(16);
        let with_secondary = CacheShadingOptions {
            secondary_cache: true,
            light_samples: 16,
            ..options(true)
        };
        let r = TileRequest {
            samples_per_pixel: 4,
            max_depth: PathDepth::constant(17),
            ..cached_request(0, 0, 16)
        };
        let first = shading(with_secondary);
        let (a, ra) = in_pool(1, || render_cached(&transport, &r, &cache(), &first)).unwrap();
        assert!(ra.secondary.records_created > 0 && ra.secondary.rays > 0);
        assert_eq!(
            a.rays,
            ra.shading.rays + ra.placement.rays + ra.secondary.rays
        );
        // Another tile builds the cache first, on two threads.
        let second = shading(with_secondary);
        let corner = TileRequest {
            width: 4,
            height: 4,
            ..r
        };
        let (_, rc) = in_pool(2, || render_cached(&transport, &corner, &cache(), &second)).unwrap();
        assert_eq!(rc.secondary, ra.secondary);
        let (b, rb) = in_pool(2, || render_cached(&transport, &r, &cache(), &second)).unwrap();
        assert_eq!(rb.secondary, PlacementReport::default());
        assert_eq!(a.image, b.image);
        assert_eq!(ra.placement, rb.placement);
        let by_paths = shading(CacheShadingOptions {
            secondary_cache: false,
            ..with_secondary
        });
        let (c, _) = render_cached(&transport, &r, &cache(), &by_paths).unwrap();
        assert_ne!(c.image, a.image);
        assert_agrees_with_path_tracing(&transport, &a, &r);
    }

    /// A tile whose probe finds more records per pixel than the limit
    /// places none, path traces its indirect light (two paths a camera ray)
    /// and takes twice the light samples; it stays reproducible and agrees
    /// with path tracing. Under a
    /// limit the probe never reaches, the tile is the same bytes as without
    /// one (the probe draws from no stream of the render's).
    #[test]
    fn tiles_too_dense_for_records_place_none_and_agree_with_path_tracing() {
        let transport = cornell(16);
        let base = CacheShadingOptions {
            light_samples: 4,
            ..options(true)
        };
        let r = TileRequest {
            samples_per_pixel: 4,
            ..cached_request(0, 0, 16)
        };
        let with_limit = |limit| {
            shading(CacheShadingOptions {
                max_records_per_pixel: Some(limit),
                ..base
            })
        };
        let (plain, plain_report) =
            render_cached(&transport, &r, &cache(), &shading(base)).unwrap();
        let records = plain_report.placement.records_created;
        assert!(records > MIN_DENSE_RECORDS, "{records} records");
        assert!(!plain_report.dense() && plain_report.probe_rays == 0);

        let loose = with_limit(1e6);
        let (same, report) = render_cached(&transport, &r, &cache(), &loose).unwrap();
        assert_eq!(same.image, plain.image);
        assert!(!report.dense() && report.probe_rays > 0);
        assert_eq!(report.placement.records_created, records);

        let tight = with_limit(1e-3);
        let (dense, report) =
            in_pool(1, || render_cached(&transport, &r, &cache(), &tight)).unwrap();
        assert!(report.dense(), "{report:?}");
        assert_eq!(report.placement.records_created, 0);
        assert_eq!(report.placement.rays, report.probe_rays);
        assert_eq!(report.shading.cache_hits, 0);
        assert!(report.shading.fallbacks > 0);
        // Twice the shadow rays of the plain tile's direct light, and paths.
        assert!(report.shading.rays > plain_report.shading.rays * 3 / 2);
        let (again, _) = in_pool(2, || render_cached(&transport, &r, &cache(), &tight)).unwrap();
        assert_eq!(again.image, dense.image);
        assert_agrees_with_path_tracing(&transport, &dense, &r);
    }

    #[test]
    fn coarse_pixels_come_first() {
        let order = coarse_to_fine(&request(0, 0, 20, 20));
        assert_eq!(order.len(), 400);
        assert_eq!(&order[..4], &[(0, 0), (16, 0), (0, 16), (16, 16)]);
        assert_eq!(order[4], (8, 0));
        let mut sorted = order.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 400);
    }
}
