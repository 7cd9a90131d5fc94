//! The secondary cache: indirect irradiance at the surfaces that records'
//! rays reach, shared by every tile and radiance query of a scene, so that a
//! record's rays stop at their first hit instead of tracing paths on
//! (docs/math.md §9.6).
//!
//! A record at `x` needs the radiance `L(y → x)` leaving each point `y` its
//! rays hit. Paths from every `y` cost most of a record and leave their noise
//! in it. The secondary cache holds records of `E_ind` at the points such
//! rays reach, made once per scene and configuration by the reproducible
//! placement pass ([`place_records`]) over a fixed candidate set: the first
//! hits of cosine-distributed rays from the camera-visible points of a
//! coarse grid of pixel centres. Records' rays then shade `y` as a camera
//! hit is shaded ([`Gather::Secondary`]): direct light by light samples and
//! `(k_d/π) E_ind(y)` from the secondary cache, placed and looked up at the
//! request's accuracy `a` (at Radiance's relaxed `2a` the Cornell box's
//! error grew from 1.46 % to 2.19 %, docs/BENCHMARKS.md "The secondary
//! cache"; the error of `E_ind(y)` is damped by the albedo and averaged
//! over the record's directions).
//!
//! Everything here is a function of the scene and the configuration only:
//! the candidates draw from [`point_rng`] with a fixed seed and the
//! placement pass is deterministic, so every tile (whatever its request,
//! thread count or replica) sees the same cache and stays reproducible.

use std::sync::Arc;

use rand::RngExt;
use rayon::prelude::*;

use super::config::{AMBIENT_MIN_DEPTH, CachedShading, PlacementOptions};
use super::placement::{PlacementCache, PlacementReport, place_records};
use super::record_estimate::{PlacementPoint, diffuse_front};
use super::secondary_caches::{SecondaryCache, SecondaryKey};
use super::shade::{CachedIntegrator, Gather};
use crate::cache::{CacheConfig, IrradianceCache, PixelFootprint};
use crate::optics::warp;
use crate::render::seed::point_rng;
use crate::render::{Cancel, PathLimits, QueryPoint, RenderError, Transport};
use crate::scene::Ray;
use crate::sphere::Frame;

/// Pixel-centre rays of the candidate grid across the image's longer side.
const GRID: u32 = 64;
/// Cosine-distributed rays from each grid point's hit.
const BOUNCES: u32 = 4;
/// Seed of the candidates' directions and the secondary records' rotations
/// and paths (fixed: the cache is a function of scene and configuration).
const SEED: u64 = 0x5eed_5ec0_dca5_e001;

/// The secondary cache of records summing `paths` for `shading`'s options
/// in `transport`'s scene, its records in a cache configured as `config`:
/// the one `shading` holds, or built now (module docs) with what building
/// it did (`SecondaryCaches::get_or_build`).
fn secondary_cache(
    transport: &Transport,
    shading: &CachedShading,
    config: CacheConfig,
    paths: PathLimits,
    cancel: &Cancel,
) -> Result<(Arc<SecondaryCache>, Option<PlacementReport>), RenderError> {
    let o = &shading.options;
    let key = SecondaryKey {
        paths,
        accuracy: o.accuracy.to_bits(),
        min_pixels: o.min_pixels.to_bits(),
        max_pixels: o.max_pixels.to_bits(),
    };
    shading.secondary.get_or_build(key, cancel, || {
        build(transport, shading, config, paths, cancel)
    })
}

/// The secondary cache that records placed by `integrator` read when their
/// rays sum `paths`: none unless its options ask for one
/// (`secondary_cache`) and `paths` are long enough for a cached bounce
/// ([`AMBIENT_MIN_DEPTH`]); otherwise [`secondary_cache`]'s for the
/// integrator's cache configuration, with what building it took if this
/// call built it (nothing otherwise).
pub fn secondary_cache_of(
    integrator: &CachedIntegrator,
    paths: PathLimits,
    cancel: &Cancel,
) -> Result<(Option<Arc<SecondaryCache>>, PlacementReport), RenderError> {
    let shading = integrator.shading;
    if !shading.options.secondary_cache || paths.max_depth < AMBIENT_MIN_DEPTH {
        return Ok((None, PlacementReport::default()));
    }
    let config = *integrator.cache.config();
    let (cache, built) = secondary_cache(integrator.transport, shading, config, paths, cancel)?;
    Ok((Some(cache), built.unwrap_or_default()))
}

/// Builds the secondary cache (module docs).
fn build(
    transport: &Transport,
    shading: &CachedShading,
    config: CacheConfig,
    paths: PathLimits,
    cancel: &Cancel,
) -> Result<(SecondaryCache, PlacementReport), RenderError> {
    let points = candidates(transport, shading)?;
    let cache = IrradianceCache::new(config)?;
    let options = PlacementOptions {
        relative_error_target: None,
        paths_per_direction: 1,
        ..shading.placement(paths, SEED)
    };
    let report = place_records(
        PlacementCache::Private(&cache),
        transport,
        &shading.rule,
        &points,
        &options,
        Gather::Paths,
        cancel,
    )?;
    Ok((SecondaryCache { cache }, report))
}

/// The candidate points (module docs), grid point by grid point. Each
/// carries the footprint of a grid pixel seen along its two segments.
fn candidates(
    transport: &Transport,
    shading: &CachedShading,
) -> Result<Vec<PlacementPoint>, RenderError> {
    let scene = transport.scene();
    let camera = &scene.camera;
    let (width, height) = camera.resolution();
    let stride = (width.max(height) / GRID).max(1);
    let (columns, rows) = (width.div_ceil(stride), height.div_ceil(stride));
    let o = &shading.options;
    let per_grid_point: Vec<Vec<PlacementPoint>> = (0..columns * rows)
        .into_par_iter()
        .map(|i| {
            let (gx, gy) = (i % columns, i / columns);
            let cx = (f64::from(gx) + 0.5) * f64::from(stride);
            let cy = (f64::from(gy) + 0.5) * f64::from(stride);
            let ray = camera.generate_ray(cx, cy);
            let Some(x) = scene.intersect(&ray) else {
                return Ok(Vec::new());
            };
            if !diffuse_front(transport, &x, ray.dir) {
                return Ok(Vec::new());
            }

            let frame = Frame::from_normal(x.shading_normal);
            let mut rng = point_rng(SEED, u64::from(i));
            let mut found = Vec::new();
            for _ in 0..BOUNCES {
                let local = warp::cosine_hemisphere([rng.random(), rng.random()]);
                let bounce: Ray = scene.spawn_ray(x.position, x.normal, frame.to_world(local));
                let Some(y) = scene.intersect(&bounce) else {
                    continue;
                };
                if !diffuse_front(transport, &y, bounce.dir) {
                    continue;
                }
                // The grid spacing seen from the camera, at y's distance
                // along the path.
                let span = camera.span_at(cx, cy, f64::from(stride), x.t + y.t);
                let size = span.max(f64::MIN_POSITIVE);
                found.push(PlacementPoint {
                    point: QueryPoint::new(y.position, y.shading_normal)?,
                    footprint: Some(PixelFootprint::new(size, o.min_pixels, o.max_pixels)?),
                });
            }
            Ok(found)
        })
        .collect::<Result<_, RenderError>>()?;
    Ok(per_grid_point.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::integrator::cached::shade::tests::assert_records_agree;
    use crate::integrator::cached::{CacheShadingOptions, default_rule_spec, indirect_paths};
    use crate::render::PathDepth;
    use crate::testing::{cornell, in_pool};

    fn shading() -> CachedShading {
        let mut spec = default_rule_spec();
        spec.samples.count = 16;
        let quadratures = Arc::new(QuadratureCache::new(1 << 24));
        CachedShading::new(spec, 4, quadratures, CacheShadingOptions::default()).unwrap()
    }

    /// The cache is built once, the same records whatever the thread count;
    /// a cancelled build leaves nothing behind; records whose rays read it
    /// agree with records whose rays trace paths, for fewer rays.
    #[test]
    fn secondary_records_agree_with_path_traced_records() {
        let transport = cornell(16);
        let paths = indirect_paths(PathDepth::constant(32));
        let config = CacheConfig::default();
        let build = |s: &CachedShading, threads, cancel: &Cancel| {
            in_pool(threads, || {
                secondary_cache(&transport, s, config, paths, cancel)
            })
        };
        let cancelled = Cancel::new();
        cancelled.cancel();
        let shading = shading();
        assert!(build(&shading, 2, &cancelled).is_err());
        let (cache, report) = build(&shading, 2, &Cancel::never()).unwrap();
        let report = report.expect("built by this call");
        assert!(report.records_created > 0 && report.rays > 0, "{report:?}");
        assert_eq!(cache.cache.stats().records, report.records_created);
        let (again, none) = build(&shading, 2, &Cancel::never()).unwrap();
        assert!(Arc::ptr_eq(&cache, &again) && none.is_none());
        let other = shading.clone();
        assert!(Arc::ptr_eq(
            &build(&other, 1, &Cancel::never()).unwrap().0,
            &cache
        ));
        let alone = self::shading();
        let (single, _) = build(&alone, 1, &Cancel::never()).unwrap();
        assert_eq!(single.cache.records(), cache.cache.records());

        let integrator = CachedIntegrator::new(&transport, &cache.cache, &shading);
        let secondary = Gather::Secondary { integrator };
        // 3 %: the secondary cache interpolates its records.
        let stats = assert_records_agree(&transport, &shading, paths, 4, secondary, 0.03);
        // 16 directions, each one segment and 4 shadow rays.
        assert!(stats.rays <= 24 * 16 * 5, "{stats:?}");
        assert!(stats.cache_hits > 0);
    }
}
