//! The secondary cache: indirect irradiance at the surfaces that records'
//! rays reach, shared by every tile of a scene, so that a record's rays
//! stop at their first hit instead of tracing paths on (docs/math.md §9.6).
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

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use rand::RngExt;
use rayon::prelude::*;

use super::config::{CachedShading, PlacementOptions};
use super::placement::{PlacementCache, PlacementReport, place_records};
use super::shade::{Gather, PlacementPoint};
use crate::cache::{Accuracy, CacheConfig, IrradianceCache, PixelFootprint};
use crate::render::seed::point_rng;
use crate::render::{Cancel, PathLimits, QueryPoint, RenderError, Transport, warp};
use crate::scene::{Ray, SurfaceHit};
use crate::sphere::Frame;

/// Pixel-centre rays of the candidate grid across the image's longer side.
const GRID: u32 = 64;
/// Cosine-distributed rays from each grid point's hit.
const BOUNCES: u32 = 4;
/// Seed of the candidates' directions and the secondary records' rotations
/// and paths (fixed: the cache is a function of scene and configuration).
const SEED: u64 = 0x5eed_5ec0_dca5_e001;

/// What identifies one secondary cache of a [`CachedShading`]: the paths
/// its records sum and the options that place them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct SecondaryKey {
    paths: PathLimits,
    /// Bits of the accuracy and of the radius bounds in pixels.
    accuracy: u64,
    min_pixels: u64,
    max_pixels: u64,
}

/// A secondary cache being built by one caller, or built.
enum Slot {
    Building,
    Built(Arc<SecondaryCache>),
}

/// The secondary caches of one scene, rule set and cache configuration,
/// built on first use (module docs). Clones share them.
#[derive(Clone, Default)]
pub struct SecondaryCaches {
    slots: Arc<Mutex<HashMap<SecondaryKey, Slot>>>,
}

/// One secondary cache, frozen, with the accuracy its lookups use.
pub struct SecondaryCache {
    pub cache: IrradianceCache,
    pub accuracy: Accuracy,
}

impl SecondaryCaches {
    /// The secondary cache of records summing `paths` for `shading`'s
    /// options in `transport`'s scene, records in a cache configured as
    /// `config`; built now if no one has, with what building it did.
    ///
    /// A caller that finds it being built runs other pool work meanwhile
    /// (`rayon::yield_now`), so on a pool thread it helps the build's
    /// parallel loops instead of idling. A build stopped by `cancel`
    /// leaves nothing behind, and the next caller builds it.
    pub fn get_or_build(
        &self,
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
        let slots = || self.slots.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            cancel.check()?;
            {
                let mut slots = slots();
                match slots.get(&key) {
                    Some(Slot::Built(found)) => return Ok((found.clone(), None)),
                    Some(Slot::Building) => {}
                    None => {
                        slots.insert(key, Slot::Building);
                        break;
                    }
                }
            }
            if rayon::yield_now() != Some(rayon::Yield::Executed) {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        match build(transport, shading, config, paths, cancel) {
            Ok((built, report)) => {
                let built = Arc::new(built);
                slots().insert(key, Slot::Built(built.clone()));
                Ok((built, Some(report)))
            }
            Err(e) => {
                slots().remove(&key);
                Err(e)
            }
        }
    }
}

/// Builds the secondary cache (module docs).
fn build(
    transport: &Transport,
    shading: &CachedShading,
    config: CacheConfig,
    paths: PathLimits,
    cancel: &Cancel,
) -> Result<(SecondaryCache, PlacementReport), RenderError> {
    let accuracy = shading.accuracy();
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
    Ok((SecondaryCache { cache, accuracy }, report))
}

/// Whether `hit`, reached along `dir`, is a front face with a diffuse lobe.
fn diffuse_front(transport: &Transport, hit: &SurfaceHit, dir: glam::DVec3) -> bool {
    hit.shading_normal.dot(dir) < 0.0
        && transport
            .bsdf(hit.material)
            .is_some_and(|b| !b.diffuse.is_black())
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
            let pixel = ray
                .dir
                .angle_between(camera.generate_ray(cx + f64::from(stride), cy).dir);
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
                let size = (pixel * (x.t + y.t)).max(f64::MIN_POSITIVE);
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
    use crate::integrator::cached::{
        CacheShadingOptions, CachedIntegrator, RecordGather, ShadingStats, compute_record,
        default_rule_spec, indirect_paths,
    };
    use crate::render::{MeanEstimate, PathDepth};
    use crate::testing::{agrees, cornell, in_pool};
    use glam::DVec3;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    fn shading() -> CachedShading {
        let mut spec = default_rule_spec();
        spec.samples.count = 16;
        let quadratures = Arc::new(QuadratureCache::new(1 << 24));
        CachedShading::new(spec, 4, quadratures, CacheShadingOptions::default()).unwrap()
    }

    /// The cache is built once, the same records whatever the thread count;
    /// a cancelled build leaves nothing behind; records whose rays read it
    /// agree with records whose rays trace paths.
    #[test]
    fn secondary_records_agree_with_path_traced_records() {
        let transport = cornell(16);
        let paths = indirect_paths(PathDepth::constant(32));
        let config = CacheConfig::default();
        let build = |s: &CachedShading, threads, cancel: &Cancel| {
            in_pool(threads, || {
                s.secondary
                    .get_or_build(&transport, s, config, paths, cancel)
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

        let target = PlacementPoint {
            // The back wall above the boxes.
            point: QueryPoint::new(DVec3::new(0.2, 0.3, -1.0), DVec3::Z).unwrap(),
            footprint: None,
        };
        let unused = IrradianceCache::new(config).unwrap();
        let integrator = CachedIntegrator {
            transport: &transport,
            cache: &cache.cache,
            shading: &shading,
        };
        let mut rng = Pcg64::seed_from_u64(5);
        let mut record = |gather: Gather, stats: &mut ShadingStats| {
            let how = RecordGather {
                paths,
                per_direction: 4,
                gather,
            };
            let limits = unused.radius_limits();
            compute_record(
                &transport,
                &shading.rule,
                &target,
                limits,
                &how,
                &mut rng,
                stats,
            )
            .unwrap()
            .irradiance
        };
        let secondary = Gather::Secondary {
            integrator,
            accuracy: cache.accuracy,
            light_samples: 4,
        };
        let mut stats = ShadingStats::default();
        let read = MeanEstimate::of((0..24).map(|_| record(secondary, &mut stats)));
        // 16 directions, each one segment and 4 shadow rays.
        assert!(stats.rays <= 24 * 16 * 5, "{stats:?}");
        assert!(stats.cache_hits > 0);
        let traced =
            MeanEstimate::of((0..24).map(|_| record(Gather::Paths, &mut ShadingStats::default())));
        let (c, t) = (read.mean.to_array(), traced.mean.to_array());
        let (vc, vt) = (
            read.variance_of_mean.to_array(),
            traced.variance_of_mean.to_array(),
        );
        for k in 0..3 {
            let se = (vc[k] + vt[k]).sqrt();
            assert!(
                // 3 %: the secondary cache interpolates its records.
                agrees(c[k], t[k], se, 4.0, 0.03),
                "channel {k}: secondary {c:?} vs paths {t:?}"
            );
        }
    }
}
