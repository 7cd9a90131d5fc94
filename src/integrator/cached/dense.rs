//! Tiles where records do not pay (docs/math.md §9.7): where the cache's
//! rules would place nearly a record per pixel (thousands of small, curved,
//! mutually occluding parts, such as the bricks of the tutorials' lego), a
//! record costs its `N` directions' paths and serves a pixel or two, which
//! is more than the camera samples' own indirect paths cost, and its
//! interpolation still leaves a bias. Such a tile places no records: each
//! camera sample's diffuse indirect light is the mean of
//! [`DENSE_INDIRECT_PATHS`] cosine-distributed paths (the shading pass's
//! miss fallback, unbiased), and its direct light takes
//! [`DENSE_LIGHT_FACTOR`] times the light samples: the records' budget goes
//! to the two terms whose noise is then left.
//!
//! Whether a tile is dense is decided before any record is computed, by a
//! probe: the placement pass over the tile's placement points, in the same
//! order and with the same coverage rule, but each record's radius taken
//! from [`PROBE_DIRECTIONS`] first segments only and no value estimated, on
//! a cache of its own. It is a function of the scene, the configuration and
//! the tile (its own random stream), so a reproducible tile stays so.

use rayon::prelude::*;

use super::config::PlacementOptions;
use super::record_estimate::{PlacementPoint, awaiting_record, lookup};
use crate::cache::{CacheConfig, CacheError, IrradianceCache};
use crate::render::seed::point_rng;
use crate::render::{Cancel, RenderError, TraceStats, Transport};
use crate::sphere::{SampleSet, SampleSetSpec};

/// Directions whose first segments give a probe record its radius (Ward's
/// harmonic mean distance); enough for the count of records, which is all
/// the probe is for.
pub const PROBE_DIRECTIONS: usize = 64;
/// A tile is dense only if its probe places more records than this, so a
/// tile that sees a few pixels of geometry keeps its records.
pub const MIN_DENSE_RECORDS: u64 = 32;
/// Light samples of a dense tile's shading points, in multiples of the
/// configuration's, and the paths of their indirect light. On the lego
/// with the `final` preset's knobs (64 camera rays per pixel, 4 light
/// samples), error over 8×8 blocks against Mitsuba's 1,024-spp image for
/// two seeds, and time (docs/BENCHMARKS.md): (1×, 1 path) 4.85 % in 9.6 s;
/// (4×, 1) 4.35/4.34 % in 21.5 s; (1×, 2) 4.90/4.06 % in 15.4 s; (2×, 2)
/// 3.99/4.14 % in 18.2 s; (1×, 4) 3.94/4.09 % in 22.3 s; (2×, 3)
/// 3.91/3.83 % in 22.7 s.
pub const DENSE_LIGHT_FACTOR: u32 = 2;
pub const DENSE_INDIRECT_PATHS: u32 = 2;
/// Seed of the probe's record rotations (its own stream: the probe draws
/// nothing from the placement's).
const PROBE_SEED: u64 = 0xde05_e7a1_e5ba_5e00;

/// What a probe found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Probe {
    /// Records the placement would create (as the probe counts them).
    pub records: u64,
    /// Rays the probe traced.
    pub rays: u64,
}

impl Probe {
    /// Whether a tile of `points` placement points with this probe is dense
    /// under a limit of `max_per_point` records per placement point.
    pub fn is_dense(&self, points: usize, max_per_point: f64) -> bool {
        self.records > MIN_DENSE_RECORDS && self.records as f64 > max_per_point * points as f64
    }
}

/// The probe of the placement of records at `points` with `options`
/// (module docs), on a cache configured as `config`.
pub fn probe(
    transport: &Transport,
    config: CacheConfig,
    directions: SampleSetSpec,
    points: &[PlacementPoint],
    options: &PlacementOptions,
    cancel: &Cancel,
) -> Result<Probe, RenderError> {
    let set = SampleSet::generate(SampleSetSpec {
        count: PROBE_DIRECTIONS,
        ..directions
    })
    .map_err(CacheError::from)?;
    let cache = IrradianceCache::new(config)?;
    let limits = cache.radius_limits();
    let mut found = Probe {
        records: 0,
        rays: 0,
    };
    for (b, batch) in points.chunks(options.batch_size).enumerate() {
        cancel.check()?;
        let first = b * options.batch_size;
        let wanted: Vec<usize> = batch
            .par_iter()
            .enumerate()
            .filter(|(_, p)| lookup(&cache, transport, &p.point, options).is_none())
            .map(|(i, _)| first + i)
            .collect();
        let records: Vec<_> = wanted
            .par_iter()
            .map(|&i| {
                let target = &points[i];
                let mut rng = point_rng(PROBE_SEED, i as u64);
                let frame = target.point.turned_frame(&mut rng);
                let mut trace = TraceStats::default();
                let distances: Vec<f64> = transport
                    .hemisphere_first_segments(
                        &target.point,
                        &frame,
                        &set.directions,
                        options.paths,
                        &mut trace,
                    )
                    .iter()
                    .map(|s| s.distance())
                    .collect();
                (awaiting_record(target, &distances, limits), trace.rays)
            })
            .collect();
        for (record, rays) in records {
            cache.insert_awaiting_values(record)?;
            found.records += 1;
            found.rays += rays;
        }
    }
    Ok(found)
}
